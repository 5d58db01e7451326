"""Music source separation into four stems, behind named backends.

Every backend takes a waveform and returns the same four stems, :data:`STEM_NAMES`: drums, bass,
vocals, other, each mono float32 with the input's length and sample rate, so that per-stem features
line up frame for frame with the features of the full mix.

Backends (:data:`STEM_BACKENDS`):

``offline``
    No model weights: harmonic/percussive separation plus frequency bands and a repetition
    (REPET-SIM) mask. The four stems sum to the input. An approximation, see
    :mod:`dancedata.compute.stems.offline`.
``openunmix``
    The OpenUnmix network (Stöter et al. 2019), pretrained ``umxhq`` or ``umxl`` weights read from a
    local folder or the torch hub cache. Needs the optional extra ``dancedata[stems]``; see
    :mod:`dancedata.compute.stems.openunmix`. The separator is loaded (weights found, read and
    built into the network) by :mod:`dancedata.io.openunmix_model` and passed to
    :func:`separate` as ``separator=``; :mod:`dancedata.featurize.stem_separation` does both.

The backends are modules of this package; what they share (:data:`STEM_NAMES`, :func:`check_audio`,
:func:`to_mono`) is in :mod:`dancedata.compute.stems.base` below them, so no backend imports this
dispatcher. Backends are imported only when used, so importing this module never imports torch.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

import numpy as np

from dancedata.compute.stems.base import STEM_NAMES, check_audio, to_mono
from dancedata.errors import InputError

__all__ = [
    "DEFAULT_BACKEND",
    "STEM_BACKENDS",
    "STEM_NAMES",
    "backend_config",
    "check_audio",
    "separate",
    "to_mono",
]

STEM_BACKENDS: tuple[str, ...] = ("offline", "openunmix")
DEFAULT_BACKEND = "offline"


def _backend_module(backend: str) -> Any:
    if backend == "offline":
        from dancedata.compute.stems import offline

        return offline
    if backend == "openunmix":
        from dancedata.compute.stems import openunmix

        return openunmix
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
    y: np.ndarray,
    sr: float,
    backend: str = DEFAULT_BACKEND,
    *,
    separator: Any = None,
    stft: np.ndarray | None = None,
    **options: Any,
) -> dict[str, np.ndarray]:
    """Split a waveform at ``sr`` Hz into {drums, bass, vocals, other}.

    ``y`` is (samples,) or (channels, samples). Each stem is mono float32 with ``y``'s length and
    sample rate. ``options`` go to the backend (see :func:`backend_config` for the names).
    ``openunmix`` needs ``separator``, loaded with
    :func:`dancedata.io.openunmix_model.load_separator`; the options that load it
    (``openunmix.LOAD_OPTIONS``: model, weights folder, device, niter, Wiener window) are not
    taken here, only its run options (chunking, memory limit). ``offline`` may be given the
    mono mix's STFT with its own ``n_fft`` and ``hop_length`` as ``stft`` (computed once per
    track and shared with other features); other backends take none.
    """
    config = backend_config(backend, **options)
    audio = check_audio(y, sr)
    module = _backend_module(backend)
    config.pop("backend")
    if backend == "openunmix":
        given = sorted(set(options) & set(module.LOAD_OPTIONS))
        if separator is None or given:
            raise InputError(
                "stem backend 'openunmix' separates with a loaded separator: load it with "
                "dancedata.io.openunmix_model.load_separator and pass separator="
                + (f" (not {', '.join(given)})" if given else "")
            )
        for name in module.LOAD_OPTIONS:
            config.pop(name)
        config["separator"] = separator
    elif separator is not None:
        raise InputError(f"stem backend {backend!r} takes no separator")
    if stft is not None:
        if backend != "offline":
            raise InputError(f"stem backend {backend!r} takes no precomputed STFT")
        config["stft"] = stft
    stems: Mapping[str, np.ndarray] = module.separate(audio, float(sr), **config)
    return {name: np.asarray(stems[name], dtype=np.float32) for name in STEM_NAMES}
