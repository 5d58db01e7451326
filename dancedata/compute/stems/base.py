"""What every stem backend shares: the stem names and the waveform checks.

Below the backends (:mod:`dancedata.compute.stems.offline`, :mod:`~.openunmix`) and the
dispatcher (:mod:`dancedata.compute.stems`), so the backends never import the dispatcher.
"""

from __future__ import annotations

import numpy as np

from dancedata.errors import InputError

STEM_NAMES: tuple[str, ...] = ("drums", "bass", "vocals", "other")

_MAX_CHANNELS = 8


def check_audio(y: np.ndarray, sr: float) -> np.ndarray:
    """Validate a waveform: (samples,) or (channels, samples), finite, sr > 0 Hz.

    Returns float32, same shape; integer PCM is scaled so that full scale is ±1. Raises
    :class:`InputError` on anything else.
    """
    if not np.isfinite(sr) or sr <= 0:
        raise InputError(f"sample rate must be a positive number of Hz, got {sr}")
    audio = np.asarray(y)
    if audio.ndim not in (1, 2) or (audio.ndim == 2 and not 1 <= audio.shape[0] <= _MAX_CHANNELS):
        raise InputError(
            f"audio must have shape (samples,) or (channels<={_MAX_CHANNELS}, samples), "
            f"got {audio.shape}"
        )
    if audio.shape[-1] == 0:
        raise InputError("audio is empty (0 samples)")
    if np.issubdtype(audio.dtype, np.integer):  # PCM: full scale → ±1
        audio = audio / float(np.iinfo(audio.dtype).max)
    elif not np.issubdtype(audio.dtype, np.floating):
        raise InputError(f"audio must be integer PCM or float, got dtype {audio.dtype}")
    audio = audio.astype(np.float32, copy=False)
    if not np.all(np.isfinite(audio)):
        raise InputError("audio contains NaN or infinite samples")
    return audio


def to_mono(y: np.ndarray) -> np.ndarray:
    """(samples,) or (channels, samples) → (samples,) float32, averaging the channels."""
    audio = np.asarray(y, dtype=np.float32)
    return audio if audio.ndim == 1 else audio.mean(axis=0)
