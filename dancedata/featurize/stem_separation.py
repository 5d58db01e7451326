"""Stem separation with every setting in one call: the OpenUnmix separator loaded, then run.

The compute functions (:func:`dancedata.compute.stems.separate`,
:func:`dancedata.compute.stems.openunmix.separate_channels`) take an already-loaded OpenUnmix
separator, because loading reads weight files (:mod:`dancedata.io.openunmix_model`) and compute
does no IO. Here, above both, the options of :data:`dancedata.compute.stems.openunmix.DEFAULTS`
are split: the ones that choose and load the separator (``LOAD_OPTIONS``: model, weights_dir,
device, niter, wiener_win_len) go to :func:`~dancedata.io.openunmix_model.load_separator`
(cached once per process per weight files and settings), the rest to the compute function.
The stems are those of the compute function with the loaded separator, bit for bit.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from dancedata.compute.stems import DEFAULT_BACKEND, StemBackend, stem_backend


def split_openunmix_options(options: dict[str, Any]) -> tuple[dict[str, Any], dict[str, Any]]:
    """``options`` → (load options for ``load_separator``, run options for compute)."""
    from dancedata.compute.stems.openunmix import LOAD_OPTIONS

    load = {name: value for name, value in options.items() if name in LOAD_OPTIONS}
    run = {name: value for name, value in options.items() if name not in LOAD_OPTIONS}
    return load, run


def openunmix_separator(**load_options: Any) -> Any:
    """The OpenUnmix separator for ``load_options`` (defaults: those of
    :data:`dancedata.compute.stems.openunmix.DEFAULTS`), loaded once per process."""
    from dancedata.compute.stems.openunmix import DEFAULTS, LOAD_OPTIONS
    from dancedata.io.openunmix_model import load_separator

    settings = {name: DEFAULTS[name] for name in LOAD_OPTIONS}
    settings.update(load_options)
    return load_separator(**settings)


def separate(
    y: np.ndarray, sr: float, backend: str | StemBackend = DEFAULT_BACKEND, **options: Any
) -> dict[str, np.ndarray]:
    """:func:`dancedata.compute.stems.separate` with ``options`` of :func:`backend_config
    <dancedata.compute.stems.backend_config>`'s names; for a backend that needs weights the
    separator is loaded from the load options first."""
    chosen = stem_backend(backend)
    chosen.config(**options)  # unknown options fail before any loading
    if not chosen.needs_weights:
        return chosen.separate(y, sr, **options)
    load, run = split_openunmix_options(options)
    return chosen.separate(y, sr, separator=openunmix_separator(**load), **run)


def separate_channels(
    audio: np.ndarray, sr: float, **options: Any
) -> tuple[dict[str, np.ndarray], dict[str, Any]]:
    """:func:`dancedata.compute.stems.openunmix.separate_channels` (stems and plan) with the
    separator loaded from the load options among ``options``; the others are its keywords."""
    from dancedata.compute.stems import openunmix

    load, run = split_openunmix_options(options)
    return openunmix.separate_channels(audio, sr, openunmix_separator(**load), **run)
