"""The FACT / AIST++ audio features, as pure functions of a mono signal.

Recipe (REFERENCE.md, "FACT/mint, 35-d"): sr = fps × hop = 60 × 512 = 30720 Hz, hop 512,
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


def log_mel(y: np.ndarray, cfg: AudioFeatureConfig) -> np.ndarray:
    """The log-power (dB) mel spectrogram both onset_strength and mfcc compute from ``y`` with
    librosa's defaults (128 mels, power 2, ref 1.0), (128, A) float32: computed once, it gives
    both the very same numbers for one STFT instead of two."""
    import librosa

    mel = librosa.feature.melspectrogram(y=y, sr=cfg.sr, n_fft=cfg.n_fft, hop_length=cfg.hop_length)
    return librosa.power_to_db(mel)


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


def chroma_cens(y: np.ndarray, cfg: AudioFeatureConfig) -> np.ndarray:
    """Chroma energy-normalised statistics, (A, 12) float32."""
    import librosa

    chroma = librosa.feature.chroma_cens(
        y=y, sr=cfg.sr, hop_length=cfg.hop_length, n_chroma=cfg.n_chroma
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
    import librosa

    kwargs = {"start_bpm": float(bpm)} if bpm else {}
    _, frames = librosa.beat.beat_track(
        onset_envelope=env,
        sr=cfg.sr,
        hop_length=cfg.hop_length,
        tightness=cfg.beat_tightness,
        units="frames",
        **kwargs,
    )
    return _one_hot(frames, env.shape[0])


def _one_hot(frames: np.ndarray, length: int) -> np.ndarray:
    out = np.zeros(length, dtype=np.uint8)
    frames = np.asarray(frames, dtype=np.int64)
    out[frames[(frames >= 0) & (frames < length)]] = 1
    return out


def fact_features(
    y: np.ndarray, bpm: float | None, cfg: AudioFeatureConfig
) -> dict[str, np.ndarray]:
    """All five FACT features of one track, trimmed to a common frame count."""
    s_db = log_mel(y, cfg)  # shared by onset_env and mfcc: one STFT, the same numbers
    env = onset_envelope(y, cfg, s_db)
    features = {
        "onset_env": env,
        "mfcc": mfcc(y, cfg, s_db),
        "chroma_cens": chroma_cens(y, cfg),
        "onset_peaks": onset_peaks(env, cfg),
        "beats": beats(env, bpm, cfg),
    }
    n = min(v.shape[0] for v in features.values())
    return {k: v[:n] for k, v in features.items()}
