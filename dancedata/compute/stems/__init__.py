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
from dataclasses import dataclass
from typing import Any

import numpy as np

from dancedata.compute.stems.base import STEM_NAMES, check_audio, to_mono
from dancedata.errors import InputError

__all__ = [
    "DEFAULT_BACKEND",
    "STEM_BACKENDS",
    "STEM_NAMES",
    "StemBackend",
    "backend_config",
    "check_audio",
    "separate",
    "stem_backend",
    "to_mono",
]

STEM_BACKENDS: tuple[str, ...] = ("offline", "openunmix")
DEFAULT_BACKEND = "offline"


@dataclass(frozen=True)
class StemBackend:
    """One stem backend, chosen once by name (:func:`stem_backend`) and asked what it needs:
    callers read its attributes instead of comparing names.

    ``needs_weights``: separates with a separator loaded from pretrained weight files and
    passed in (``separator=``; the options naming and loading it are :attr:`load_options`);
    its config records the weights rather than an arithmetic revision. ``takes_stft``: may be
    given the mono mix's STFT (computed once per track and shared with other features).
    ``libraries``: the optional libraries it imports (recorded with the versions used).
    """

    name: str
    module_name: str
    needs_weights: bool
    takes_stft: bool
    libraries: tuple[str, ...] = ()

    def module(self) -> Any:
        """The compute module that separates (imported on first use)."""
        import importlib

        return importlib.import_module(self.module_name)

    @property
    def defaults(self) -> dict[str, Any]:
        """Every option the backend takes, with its default value."""
        return dict(self.module().DEFAULTS)

    @property
    def load_options(self) -> tuple[str, ...]:
        """The options that choose and load its separator (none without weights)."""
        return tuple(self.module().LOAD_OPTIONS) if self.needs_weights else ()

    def config(self, **options: Any) -> dict[str, Any]:
        """Every setting the backend will use (its defaults overlaid with ``options``), plus
        its name (see :func:`backend_config`)."""
        defaults = self.defaults
        unknown = sorted(set(options) - set(defaults))
        if unknown:
            raise InputError(
                f"unknown option(s) for stem backend {self.name!r}: {', '.join(unknown)}; "
                f"known: {', '.join(sorted(defaults))}"
            )
        return {"backend": self.name, **defaults, **options}

    def separate(
        self,
        y: np.ndarray,
        sr: float,
        *,
        separator: Any = None,
        stft: np.ndarray | None = None,
        **options: Any,
    ) -> dict[str, np.ndarray]:
        """:func:`separate` with this backend."""
        return separate(y, sr, self, separator=separator, stft=stft, **options)


_REGISTRY: dict[str, StemBackend] = {
    "offline": StemBackend(
        "offline", "dancedata.compute.stems.offline", needs_weights=False, takes_stft=True
    ),
    "openunmix": StemBackend(
        "openunmix",
        "dancedata.compute.stems.openunmix",
        needs_weights=True,
        takes_stft=False,
        libraries=("torch", "torchaudio", "openunmix"),
    ),
}


def stem_backend(backend: str | StemBackend = DEFAULT_BACKEND) -> StemBackend:
    """The backend named ``backend`` (a backend is returned as is); InputError for an unknown
    name, listing the known ones."""
    if isinstance(backend, StemBackend):
        return backend
    found = _REGISTRY.get(backend)
    if found is None:
        raise InputError(
            f"unknown stem backend {backend!r}; choose one of {', '.join(STEM_BACKENDS)}"
        )
    return found


def backend_config(backend: str | StemBackend = DEFAULT_BACKEND, **options: Any) -> dict[str, Any]:
    """Every setting the backend will use (its defaults overlaid with ``options``), plus its name.

    Cheap (imports no model library), JSON-serialisable, and meant for manifests, Zarr attrs and
    per-song cache keys: two calls with equal configs give the same stems for the same audio.
    """
    return stem_backend(backend).config(**options)


def separate(
    y: np.ndarray,
    sr: float,
    backend: str | StemBackend = DEFAULT_BACKEND,
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
    chosen = stem_backend(backend)
    config = chosen.config(**options)
    audio = check_audio(y, sr)
    module = chosen.module()
    config.pop("backend")
    if chosen.needs_weights:
        given = sorted(set(options) & set(chosen.load_options))
        if separator is None or given:
            raise InputError(
                f"stem backend {chosen.name!r} separates with a loaded separator: load it with "
                "dancedata.io.openunmix_model.load_separator and pass separator="
                + (f" (not {', '.join(given)})" if given else "")
            )
        for name in chosen.load_options:
            config.pop(name)
        config["separator"] = separator
    elif separator is not None:
        raise InputError(f"stem backend {chosen.name!r} takes no separator")
    if stft is not None:
        if not chosen.takes_stft:
            raise InputError(f"stem backend {chosen.name!r} takes no precomputed STFT")
        config["stft"] = stft
    stems: Mapping[str, np.ndarray] = module.separate(audio, float(sr), **config)
    return {name: np.asarray(stems[name], dtype=np.float32) for name in STEM_NAMES}
