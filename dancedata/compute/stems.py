"""Music source separation into four stems, behind named backends.

Every backend takes a waveform and returns the same four stems, :data:`STEM_NAMES`: drums, bass,
vocals, other, each mono float32 with the input's length and sample rate, so that per-stem features
line up frame for frame with the features of the full mix.

Backends (:data:`STEM_BACKENDS`):

``offline``
    No model weights: harmonic/percussive separation plus frequency bands and a repetition
    (REPET-SIM) mask. The four stems sum to the input. An approximation, see
    :mod:`dancedata.compute.stems_offline`.
``openunmix``
    The OpenUnmix network (Stöter et al. 2019), pretrained ``umxhq`` or ``umxl`` weights read from a
    local folder or the torch hub cache. Needs the optional extra ``dancedata[stems]``; see
    :mod:`dancedata.compute.stems_openunmix`.

Backends are imported only when used, so importing this module never imports torch.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

import numpy as np

from dancedata.errors import InputError

STEM_NAMES: tuple[str, ...] = ("drums", "bass", "vocals", "other")
STEM_BACKENDS: tuple[str, ...] = ("offline", "openunmix")
DEFAULT_BACKEND = "offline"

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


def _backend_module(backend: str) -> Any:
    if backend == "offline":
        from dancedata.compute import stems_offline

        return stems_offline
    if backend == "openunmix":
        from dancedata.compute import stems_openunmix

        return stems_openunmix
    raise InputError(f"unknown stem backend {backend!r}; choose one of {', '.join(STEM_BACKENDS)}")


def backend_config(backend: str = DEFAULT_BACKEND, **options: Any) -> dict[str, Any]:
    """Every setting the backend will use (its defaults overlaid with ``options``), plus its name.

    Cheap (imports no model library), JSON-serialisable, and meant for manifests, Zarr attrs and
    per-song cache keys: two calls with equal configs give the same stems for the same audio.
    """
    module = _backend_module(backend)
    unknown = sorted(set(options) - set(module.DEFAULTS))
    if unknown:
        raise InputError(
            f"unknown option(s) for stem backend {backend!r}: {', '.join(unknown)}; "
            f"known: {', '.join(sorted(module.DEFAULTS))}"
        )
    return {"backend": backend, **module.DEFAULTS, **options}


def separate(
    y: np.ndarray, sr: float, backend: str = DEFAULT_BACKEND, **options: Any
) -> dict[str, np.ndarray]:
    """Split a waveform at ``sr`` Hz into {drums, bass, vocals, other}.

    ``y`` is (samples,) or (channels, samples). Each stem is mono float32 with ``y``'s length and
    sample rate. ``options`` go to the backend (see :func:`backend_config` for the names).
    """
    config = backend_config(backend, **options)
    audio = check_audio(y, sr)
    module = _backend_module(backend)
    config.pop("backend")
    stems: Mapping[str, np.ndarray] = module.separate(audio, float(sr), **config)
    return {name: np.asarray(stems[name], dtype=np.float32) for name in STEM_NAMES}
