"""The FACT / AIST++ audio features, as pure functions of a mono signal.

Recipe (docs/FORMATS.md, "FACT/mint, 35-d"): sr = fps × hop = 60 × 512 = 30720 Hz, hop 512,
n_fft 2048, Hann window, so feature frame i sits at i / 60 s and meets motion frame i.

- ``onset_env``   spectral-flux onset strength, librosa.onset.onset_strength
- ``mfcc``        20 MFCC, librosa.feature.mfcc
- ``chroma_cens`` 12 chroma energy-normalised statistics, librosa.feature.chroma_cens
- ``onset_peaks`` 1 on frames picked by librosa.onset.onset_detect on that envelope
- ``beats``       1 on beats from librosa.beat.beat_track with the music's BPM as start_bpm and
                  tightness 100 (AIST++ music is 4/4 at a known constant tempo)
"""

from __future__ import annotations

from dataclasses import asdict, dataclass

import numpy as np

FACT_FEATURES: tuple[str, ...] = ("onset_env", "mfcc", "chroma_cens", "onset_peaks", "beats")


@dataclass(frozen=True)
class AudioFeatureConfig:
    """Parameters of the FACT recipe; every field changes the numbers, so all are recorded."""

    fps: float = 60.0
    hop_length: int = 512
    n_fft: int = 2048
    n_mfcc: int = 20
    n_chroma: int = 12
    beat_tightness: float = 100.0
    # librosa res_type of the decode to ``sr`` (featurize --resampler): soxr_hq is librosa.load's
    # default since 0.10; kaiser_best (resampy) was its default before, and FACT-era features
    # were made with it. The two differ by about 1 % in MFCC and onset strength.
    res_type: str = "soxr_hq"

    @property
    def sr(self) -> int:
        """Sample rate that puts one feature frame on every motion frame: fps × hop."""
        return int(round(self.fps * self.hop_length))

    def as_dict(self) -> dict[str, float | int]:
        return {**asdict(self), "sr": self.sr}


def log_mel(y: np.ndarray, cfg: AudioFeatureConfig, mag: np.ndarray | None = None) -> np.ndarray:
    """The log-power (dB) mel spectrogram both onset_strength and mfcc compute from ``y`` with
    librosa's defaults (128 mels, power 2, ref 1.0), (128, A) float32: computed once, it gives
    both the very same numbers for one STFT instead of two. ``mag`` is |STFT| of ``y``
    (``n_fft``, ``hop_length``, Hann, centred) when already computed: squared, it is the very
    power spectrogram melspectrogram(y=...) computes."""
    import librosa

    if mag is not None:
        mel = librosa.feature.melspectrogram(S=mag**2.0, sr=cfg.sr, n_fft=cfg.n_fft)
    else:
        mel = librosa.feature.melspectrogram(
            y=y, sr=cfg.sr, n_fft=cfg.n_fft, hop_length=cfg.hop_length
        )
    return librosa.power_to_db(mel)


def stft(y: np.ndarray, cfg: AudioFeatureConfig) -> np.ndarray:
    """``librosa.stft`` of ``y`` with the recipe's ``n_fft`` and ``hop_length`` (Hann, centred),
    (1 + n_fft / 2, A) complex64: the one STFT of the mix that the mel spectrogram, the tuning
    estimate of chroma_cens and the offline stems share."""
    import librosa

    return librosa.stft(np.asarray(y, dtype=np.float32), n_fft=cfg.n_fft, hop_length=cfg.hop_length)


def onset_envelope(
    y: np.ndarray, cfg: AudioFeatureConfig, s_db: np.ndarray | None = None
) -> np.ndarray:
    """Spectral-flux onset strength, (A,) float32 (from ``s_db`` = :func:`log_mel` if given)."""
    import librosa

    if s_db is not None:
        env = librosa.onset.onset_strength(
            S=s_db, sr=cfg.sr, hop_length=cfg.hop_length, n_fft=cfg.n_fft
        )
        return env.astype(np.float32)
    env = librosa.onset.onset_strength(y=y, sr=cfg.sr, hop_length=cfg.hop_length, n_fft=cfg.n_fft)
    return env.astype(np.float32)


def mfcc(y: np.ndarray, cfg: AudioFeatureConfig, s_db: np.ndarray | None = None) -> np.ndarray:
    """MFCC, (A, n_mfcc) float32 (from ``s_db`` = :func:`log_mel` if given)."""
    import librosa

    if s_db is not None:
        return librosa.feature.mfcc(S=s_db, n_mfcc=cfg.n_mfcc).T.astype(np.float32)
    coeffs = librosa.feature.mfcc(
        y=y, sr=cfg.sr, n_mfcc=cfg.n_mfcc, hop_length=cfg.hop_length, n_fft=cfg.n_fft
    )
    return coeffs.T.astype(np.float32)


def chroma_cens(
    y: np.ndarray, cfg: AudioFeatureConfig, mag: np.ndarray | None = None
) -> np.ndarray:
    """Chroma energy-normalised statistics, (A, 12) float32.

    The CQT under it first estimates the tuning by ``librosa.estimate_tuning`` (36 bins per
    octave, chroma_cqt's), whose pitch tracker takes |STFT| with n_fft 2048 and hop 512; when
    ``mag`` is that very |STFT| (the recipe's defaults) it is handed over instead of being
    computed again, and the tuning, hence every value, is the same. The CQT itself is
    :func:`dancedata.compute.constant_q.cqt_magnitude` (librosa's numbers, filter banks reused
    between tracks of one tuning).
    """
    import librosa

    from dancedata.compute.constant_q import cqt_magnitude, estimate_tuning_from_magnitude

    if mag is not None and cfg.n_fft == 2048 and cfg.hop_length == 512:
        # librosa.estimate_tuning(S=mag, ...)'s value, from the pitch band's bins only
        tuning = estimate_tuning_from_magnitude(mag, cfg.sr, cfg.n_fft, bins_per_octave=36)
    else:  # what chroma_cens's CQT estimates when given no tuning
        tuning = librosa.estimate_tuning(y=y, sr=cfg.sr, bins_per_octave=36)
    # chroma_cens's own CQT (7 octaves of 36 bins from C1), with the filter banks kept between
    # tracks (compute.constant_q): the same |CQT|, hence the same chroma
    cqt = cqt_magnitude(y, cfg.sr, cfg.hop_length, n_bins=7 * 36, bins_per_octave=36, tuning=tuning)
    chroma = librosa.feature.chroma_cens(
        C=cqt, sr=cfg.sr, hop_length=cfg.hop_length, n_chroma=cfg.n_chroma
    )
    return chroma.T.astype(np.float32)


def onset_peaks(env: np.ndarray, cfg: AudioFeatureConfig) -> np.ndarray:
    """One-hot (A,) uint8 of onsets picked on the onset envelope ``env``."""
    import librosa

    peaks = librosa.onset.onset_detect(
        onset_envelope=env, sr=cfg.sr, hop_length=cfg.hop_length, units="frames"
    )
    return _one_hot(peaks, env.shape[0])


def beats(env: np.ndarray, bpm: float | None, cfg: AudioFeatureConfig) -> np.ndarray:
    """One-hot (A,) uint8 of tracked beats; ``bpm`` (the music's known tempo) seeds the
    tracker as start_bpm. Without a known tempo librosa's default prior (120 BPM) is used."""
    return _one_hot(beat_frames(env, bpm, cfg), env.shape[0])


def beat_frames(env: np.ndarray, bpm: float | None, cfg: AudioFeatureConfig) -> np.ndarray:
    """Beat frames of ``librosa.beat.beat_track(onset_envelope=env, start_bpm=bpm or 120,
    tightness=cfg.beat_tightness, trim=True)``, the same frames (librosa 0.11's algorithm: tempo
    by ``librosa.feature.tempo``, Ellis's dynamic program, last beat above half the median
    cumulative score of the local maxima, weak leading and trailing beats trimmed), without
    importing librosa.beat, which compiles a numba kernel at import without caching it (1-3 s
    per process); the loops here are compiled once per machine
    (:mod:`dancedata.compute.jit_kernels`)."""
    import librosa

    from dancedata.compute.jit_kernels import (
        beat_backtrack_and_trim,
        beat_local_score,
        beat_track_dp,
    )

    onsets = np.asarray(env)
    if not onsets.any():
        return np.zeros(0, dtype=np.int64)
    tempo = librosa.feature.tempo(
        onset_envelope=onsets,
        sr=cfg.sr,
        hop_length=cfg.hop_length,
        start_bpm=float(bpm) if bpm else 120.0,
    )
    tempo = np.atleast_1d(tempo)
    if np.any(tempo <= 0):
        raise ValueError(f"estimated tempo {tempo} must be strictly positive")
    frames_per_beat = float(np.round(float(cfg.sr) / cfg.hop_length * 60.0 / tempo)[0])
    normalised = onsets / (onsets.std(ddof=1, axis=-1, keepdims=True) + librosa.util.tiny(onsets))
    localscore = beat_local_score(normalised.astype(np.float64), frames_per_beat)
    tightness = float(np.float32(cfg.beat_tightness))  # librosa's DP takes it as float32
    backlink, cumscore = beat_track_dp(localscore, frames_per_beat, tightness)
    peaks = librosa.util.localmax(cumscore, axis=-1)
    threshold = 0.5 * np.ma.getdata(np.ma.median(np.ma.masked_array(cumscore, mask=~peaks)))
    tail = len(cumscore) - 1
    for frame in range(len(cumscore) - 1, -1, -1):
        if peaks[frame] and cumscore[frame] >= threshold:
            tail = frame
            break
    return np.flatnonzero(beat_backtrack_and_trim(localscore, backlink, tail, True))


def _one_hot(frames: np.ndarray, length: int) -> np.ndarray:
    out = np.zeros(length, dtype=np.uint8)
    frames = np.asarray(frames, dtype=np.int64)
    out[frames[(frames >= 0) & (frames < length)]] = 1
    return out


def fact_features(
    y: np.ndarray, bpm: float | None, cfg: AudioFeatureConfig, spec: np.ndarray | None = None
) -> dict[str, np.ndarray]:
    """All five FACT features of one track, trimmed to a common frame count. ``spec`` is
    :func:`stft` of ``y`` when already computed (shared with the offline stems)."""
    mag = np.abs(spec if spec is not None else stft(y, cfg))
    s_db = log_mel(y, cfg, mag)  # shared by onset_env and mfcc: one STFT, the same numbers
    env = onset_envelope(y, cfg, s_db)
    features = {
        "onset_env": env,
        "mfcc": mfcc(y, cfg, s_db),
        "chroma_cens": chroma_cens(y, cfg, mag),
        "onset_peaks": onset_peaks(env, cfg),
        "beats": beats(env, bpm, cfg),
    }
    n = min(v.shape[0] for v in features.values())
    return {k: v[:n] for k, v in features.items()}
