"""Per-stem audio features and the weighted stem onset curve of the keyframe thesis.

Each stem gets the FACT/AIST++ recipe (onset strength, 20 MFCC, onset peaks), computed exactly as
for the full mix: ``librosa.onset.onset_strength``, ``librosa.feature.mfcc(n_mfcc=20)`` and
``librosa.onset.onset_detect(onset_envelope=...)``, with Hann-windowed STFTs of ``n_fft`` samples
every ``hop_length`` samples, centred. At sr = 30720 Hz and hop 512 that is 60 frames per second,
the AIST++ motion frame rate; a signal of n samples gives A = 1 + n // hop_length frames.

The thesis's "weighted stem onsets" keyframe curve is Σ_stem w_stem · onset_env_stem.
"""

from __future__ import annotations

from collections.abc import Mapping

import numpy as np

from dancedata.errors import InputError

STEM_FEATURE_NAMES: tuple[str, ...] = ("onset_env", "mfcc", "onset_peaks")
DEFAULT_STEM_WEIGHTS: dict[str, float] = {"drums": 1.0, "bass": 1.0, "vocals": 1.0, "other": 1.0}


def n_feature_frames(n_samples: int, hop_length: int = 512) -> int:
    """Frames of a centred STFT: 1 + n_samples // hop_length."""
    return 1 + int(n_samples) // int(hop_length)


def stem_features(
    y: np.ndarray,
    sr: float,
    hop_length: int = 512,
    n_fft: int = 2048,
    n_mfcc: int = 20,
    mag: np.ndarray | None = None,
) -> dict[str, np.ndarray]:
    """FACT-style features of one mono stem at ``sr`` Hz, one row per hop of ``hop_length``.

    Returns ``onset_env`` (A,) float32 (spectral flux of the log-mel spectrogram), ``mfcc``
    (A, n_mfcc) float32 and ``onset_peaks`` (A,) uint8 (1 where ``onset_detect`` on that envelope
    fires). A silent stem (Ballet Jazz has no drums) gives a zero envelope and no peaks.
    ``mag`` is :func:`stem_magnitude` of ``y`` when already computed (the drums stem's is
    shared with its NMFD).
    """
    import librosa

    signal = np.asarray(y, dtype=np.float32)
    if signal.ndim != 1 or signal.size == 0:
        raise InputError(f"a stem must be a non-empty mono signal, got shape {signal.shape}")
    if mag is None:
        mag = stem_magnitude(signal, hop_length, n_fft)
    # onset_strength(y=...) and mfcc(y=...) each compute this same log-power mel spectrogram
    # (128 bands up to sr / 2) from |STFT|²; computed once and handed to both, the numbers are
    # unchanged.
    mel_db = librosa.power_to_db(librosa.feature.melspectrogram(S=mag**2.0, sr=sr, n_fft=n_fft))
    env = librosa.onset.onset_strength(S=mel_db, sr=sr, hop_length=hop_length, n_fft=n_fft)
    mfcc = librosa.feature.mfcc(S=mel_db, sr=sr, n_mfcc=n_mfcc).T
    peaks = np.zeros(env.shape[0], dtype=np.uint8)
    if np.any(env > 0):
        idx = librosa.onset.onset_detect(onset_envelope=env, sr=sr, hop_length=hop_length)
        peaks[idx] = 1
    return {
        "onset_env": env.astype(np.float32),
        "mfcc": np.ascontiguousarray(mfcc, dtype=np.float32),
        "onset_peaks": peaks,
    }


def stem_magnitude(y: np.ndarray, hop_length: int = 512, n_fft: int = 2048) -> np.ndarray:
    """|STFT| of a mono signal, (1 + n_fft / 2, 1 + n // hop_length) float32: Hann window,
    centred, as librosa.feature.melspectrogram(y=...) and the NMFD of the drums take it."""
    import librosa

    signal = np.asarray(y, dtype=np.float32)
    return np.abs(librosa.stft(signal, n_fft=n_fft, hop_length=hop_length))


def all_stem_features(
    stems: Mapping[str, np.ndarray],
    sr: float,
    hop_length: int = 512,
    n_fft: int = 2048,
    n_mfcc: int = 20,
    mags: Mapping[str, np.ndarray] | None = None,
) -> dict[str, dict[str, np.ndarray]]:
    """:func:`stem_features` for every stem: {stem: {feature: array}}; ``mags`` holds
    :func:`stem_magnitude` of the stems already computed."""
    mags = mags or {}
    return {
        name: stem_features(
            signal, sr, hop_length=hop_length, n_fft=n_fft, n_mfcc=n_mfcc, mag=mags.get(name)
        )
        for name, signal in stems.items()
    }


def weighted_curve(
    curves: Mapping[str, np.ndarray],
    weights: Mapping[str, float],
    normalize: bool = False,
) -> np.ndarray:
    """Σ_name weights[name] · curves[name], float32 (A,).

    Every weighted name must have a curve, and all curves the same length. With ``normalize``
    each curve is first divided by its maximum (a zero curve stays zero), so the weights compare
    shapes rather than loudness. Names with weight 0 may be absent.
    """
    used = {name: float(w) for name, w in weights.items() if float(w) != 0.0}
    missing = sorted(set(used) - set(curves))
    if missing:
        raise InputError(f"weights name curve(s) that are missing: {', '.join(missing)}")
    lengths = {np.asarray(c).shape for c in curves.values()}
    if len(lengths) != 1 or len(next(iter(lengths))) != 1:
        raise InputError(f"curves must be 1-d and of one length, got shapes {sorted(lengths)}")
    total = np.zeros(next(iter(lengths)), dtype=np.float64)
    for name, weight in used.items():
        curve = np.asarray(curves[name], dtype=np.float64)
        if normalize:
            peak = curve.max(initial=0.0)
            curve = curve / peak if peak > 0 else curve
        total += weight * curve
    return total.astype(np.float32)


def weighted_stem_onsets(
    onsets: Mapping[str, np.ndarray],
    weights: Mapping[str, float] | None = None,
    normalize: bool = False,
) -> np.ndarray:
    """The thesis's weighted stem onset curve Σ_stem w_stem · onset_env_stem, (A,) float32.

    ``onsets`` maps stem name → onset envelope (A,). ``weights`` defaults to
    :data:`DEFAULT_STEM_WEIGHTS` (all 1: the plain sum); see :func:`weighted_curve` for
    ``normalize``.
    """
    return weighted_curve(onsets, DEFAULT_STEM_WEIGHTS if weights is None else weights, normalize)
