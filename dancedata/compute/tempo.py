"""Global tempo of a piece of music, with its metrical alternatives and a confidence.

The estimate is the one ``librosa.beat.beat_track`` returns (and ingest has always recorded),
computed without the beat tracker's dynamic programme, which costs seconds of numba compilation
per process and is not needed for the tempo:

1. onset strength: ``librosa.onset.onset_strength(aggregate=np.median)`` on mono audio at
   ``sr`` Hz with hop ``hop_length`` (beat_track's envelope; one mel STFT, ~0.1 CPU-s a minute
   of music at 22050 Hz);
2. autocorrelation tempogram (Grosche et al.; ``librosa.feature.tempogram``): Hann windows of
   ``ac_size`` s centred on every frame (envelope padded by a linear ramp to 0), each window's
   autocorrelation normalised to a maximum of 1, averaged over time;
3. the lag maximising ``log1p(1e6 · tempogram) + log-prior``, where the log-prior is a
   log-normal around ``start_bpm`` with ``std_bpm`` octaves, and lags faster than
   ``max_tempo`` are excluded (``librosa.feature.tempo``'s rule). BPM = 60 · sr / (hop · lag).

Steps 2 and 3 are written here in numpy (tests compare them to librosa's own functions).

Alternatives are half and double the estimate. **Confidence** of a tempo ``b`` among the three
candidates ``{estimate, half, double}``: the mean tempogram value at the lag of ``b`` (nearest
lag; 0 outside the lag range), divided by the sum of the three. It says how strongly the
periodicity at the estimate dominates its metrical neighbours (1/3 each when they are equal).

The sample rate matters: at 11025 Hz (a "low-rate" envelope) the Vibe Ace track estimates
103.4 BPM instead of 129.2, because its hi-hats above 5.5 kHz carry the beat, so the default
stays 22050 Hz.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

TEMPO_SR = 22050
TEMPO_HOP = 512
AC_SIZE_S = 8.0
START_BPM = 120.0
STD_BPM = 1.0
MAX_TEMPO = 320.0


@dataclass(frozen=True)
class TempoEstimate:
    """A global tempo in beats per minute with its half and double, and each one's confidence
    (its share of the three candidates' mean tempogram strength, see the module docstring)."""

    bpm: float
    confidence: float
    half_bpm: float
    half_confidence: float
    double_bpm: float
    double_confidence: float

    def as_dict(self) -> dict[str, float]:
        return {
            "bpm": self.bpm,
            "confidence": self.confidence,
            "half_bpm": self.half_bpm,
            "half_confidence": self.half_confidence,
            "double_bpm": self.double_bpm,
            "double_confidence": self.double_confidence,
        }

    def stronger_alternative(self) -> str | None:
        """``"half"`` or ``"double"`` when that candidate's confidence exceeds the estimate's (the
        estimate follows the tempo prior, the confidence does not), else None."""
        best = max(
            ("half", self.half_confidence), ("double", self.double_confidence), key=lambda x: x[1]
        )
        return best[0] if best[1] > self.confidence else None

    def line(self) -> str:
        """One line: ``129.2 BPM (confidence 0.52; half 64.6: 0.21, double 258.4: 0.27)``."""
        return (
            f"{self.bpm:.1f} BPM (confidence {self.confidence:.2f}; half {self.half_bpm:.1f}: "
            f"{self.half_confidence:.2f}, double {self.double_bpm:.1f}: "
            f"{self.double_confidence:.2f})"
        )


def onset_envelope(y: np.ndarray, sr: int = TEMPO_SR, hop_length: int = TEMPO_HOP) -> np.ndarray:
    """(frames,) onset strength of mono ``y`` as ``librosa.beat.beat_track`` computes it."""
    import librosa

    return librosa.onset.onset_strength(
        y=np.ascontiguousarray(y, dtype=np.float32), sr=sr, hop_length=hop_length,
        aggregate=np.median,
    )  # fmt: skip


def mean_tempogram(envelope: np.ndarray, win_length: int) -> np.ndarray:
    """(win_length,) time-averaged autocorrelation tempogram of an onset envelope: lag 0 …
    win_length − 1 frames (``librosa.feature.tempogram(center=True, window="hann")`` averaged
    over frames)."""
    from scipy.fft import irfft, next_fast_len, rfft
    from scipy.signal import get_window

    env = np.asarray(envelope, dtype=np.float64)
    n = env.shape[0]
    half = win_length // 2
    padded = np.pad(env, (half, half), mode="linear_ramp", end_values=(0, 0))
    frames = np.lib.stride_tricks.sliding_window_view(padded, win_length)[:n]
    windowed = frames * get_window("hann", win_length, fftbins=True)
    size = next_fast_len(2 * win_length - 1, real=True)
    spectrum = rfft(windowed, n=size, axis=1)
    auto = irfft(spectrum.real**2 + spectrum.imag**2, n=size, axis=1)[:, :win_length]
    peak = np.abs(auto).max(axis=1, keepdims=True)
    auto = np.divide(auto, peak, out=np.zeros_like(auto), where=peak > np.finfo(float).tiny)
    return auto.mean(axis=0)


def lag_bpms(win_length: int, sr: int, hop_length: int) -> np.ndarray:
    """(win_length,) BPM of each lag (lag 0: inf)."""
    lags = np.arange(win_length, dtype=np.float64)
    with np.errstate(divide="ignore"):
        return 60.0 * sr / (hop_length * lags)


def estimate_tempo(
    envelope: np.ndarray,
    sr: int = TEMPO_SR,
    hop_length: int = TEMPO_HOP,
    *,
    ac_size: float = AC_SIZE_S,
    start_bpm: float = START_BPM,
    std_bpm: float = STD_BPM,
    max_tempo: float = MAX_TEMPO,
) -> TempoEstimate:
    """The global tempo of an onset envelope at ``sr / hop_length`` frames per second (see the
    module docstring); ``bpm`` 0 with confidences 0 when the envelope is silent."""
    env = np.asarray(envelope, dtype=np.float64)
    if env.ndim != 1:
        raise ValueError(f"onset envelope must be 1-d (got shape {env.shape})")
    if not env.size or not env.any():
        return TempoEstimate(0.0, 0.0, 0.0, 0.0, 0.0, 0.0)
    win_length = int(np.floor(ac_size * sr / hop_length))  # librosa.time_to_frames
    tg = mean_tempogram(env, win_length)
    bpms = lag_bpms(win_length, sr, hop_length)
    with np.errstate(divide="ignore"):
        logprior = -0.5 * ((np.log2(bpms) - np.log2(start_bpm)) / std_bpm) ** 2
    logprior[: int(np.argmax(bpms < max_tempo))] = -np.inf
    best = int(np.argmax(np.log1p(1e6 * tg) + logprior))
    bpm = float(bpms[best])
    candidates = (bpm, bpm / 2.0, bpm * 2.0)
    strengths = np.array([_strength(tg, bpms, b) for b in candidates])
    total = float(strengths.sum())
    shares = strengths / total if total > 0 else np.zeros(3)
    return TempoEstimate(
        bpm, float(shares[0]), candidates[1], float(shares[1]), candidates[2], float(shares[2])
    )


def _strength(tg: np.ndarray, bpms: np.ndarray, bpm: float) -> float:
    """Mean tempogram value (≥ 0) at the lag nearest to ``bpm``; 0 outside the lag range."""
    lag = int(round(bpms[1] / bpm))  # bpms[1] = 60·sr/hop, the BPM of lag 1
    if not 1 <= lag < tg.shape[0]:
        return 0.0
    return max(0.0, float(tg[lag]))
