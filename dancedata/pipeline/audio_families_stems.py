"""Stem families: per-stem FACT features and the NMFD of the drums stem.

Both families read the four stems of the track (drums, bass, vocals, other) from the track's
shared context (:meth:`TrackAudio.shared`, key :data:`SEPARATE_KEY`), so the track is separated
once however many stem families run; when every stem family of a track comes from the feature
cache, it is not separated at all.

``stems`` writes ``audio/stems/<stem>/onset_env`` (A,) float32, ``.../mfcc`` (A, n_mfcc) float32
and ``.../onset_peaks`` (A,) uint8 for each stem, by the FACT recipe at the store's feature rate
(:mod:`dancedata.compute.stem_features`). ``nmfd`` writes ``audio/nmfd_drums`` (A, 3) float32,
the kick, snare and hi-hat activations of the drums stem (:mod:`dancedata.compute.nmfd`).

The stem backend's full configuration (:func:`stem_backend_config`) is part of both families'
config, so it reaches the manifest, the fingerprint and the cache key; for ``openunmix`` it holds
each weight file's name and sha256 instead of the folder it was found in, so other weights
change the fingerprint and moving the same weights does not.
"""

from __future__ import annotations

import functools
from typing import Any

import numpy as np

from dancedata.compute.audio_features import AudioFeatureConfig
from dancedata.compute.nmfd import NMFD_COMPONENTS, NMFD_DIVERGENCE
from dancedata.compute.stem_features import STEM_FEATURE_NAMES
from dancedata.compute.stems import STEM_NAMES
from dancedata.pipeline.audio_family_base import (
    BASE_LIBRARIES,
    STEM_CHOICES,
    ArraySpec,
    AudioFamily,
    AudioSettings,
    TrackAudio,
)
from dancedata.store.checksums import sha256_file

SEPARATE_KEY = "separate"
_DEFAULT = AudioSettings()


@functools.lru_cache(maxsize=32)
def _file_sha256(path: str, size: int, mtime_ns: int) -> str:
    return sha256_file(path)


def weights_checksums(model: str, weights_dir: str | None) -> dict[str, dict[str, str]]:
    """{stem: {"file": name, "sha256": hex}} of the OpenUnmix weight files featurize would load
    (see :func:`dancedata.compute.stems_openunmix.find_weights`; hashed once per process)."""
    from dancedata.compute.stems_openunmix import find_weights

    out: dict[str, dict[str, str]] = {}
    for stem, path in find_weights(model, weights_dir).items():
        stat = path.stat()
        out[stem] = {
            "file": path.name,
            "sha256": _file_sha256(str(path), stat.st_size, stat.st_mtime_ns),
        }
    return out


def separation_options(settings: AudioSettings) -> dict[str, Any]:
    """Keyword options for :func:`dancedata.compute.stems.separate` with ``settings``."""
    if settings.stems == "openunmix":
        return {
            "model": settings.stems_model,
            "weights_dir": settings.stems_weights,
            "device": settings.stems_device,
        }
    return {}


def stem_backend_config(settings: AudioSettings) -> dict[str, Any]:
    """Every setting of the stem backend (see :func:`dancedata.compute.stems.backend_config`);
    for ``openunmix`` the weights folder is replaced by the weight files' names and sha256."""
    from dancedata.compute.stems import backend_config

    config = backend_config(settings.stems, **separation_options(settings))
    if settings.stems == "openunmix":
        config.pop("weights_dir", None)
        config["weights"] = weights_checksums(settings.stems_model, settings.stems_weights)
    return config


def track_stems(track: TrackAudio, settings: AudioSettings) -> dict[str, np.ndarray]:
    """The track's four stems (mono float32 at ``cfg.sr``), separated once per track."""
    from dancedata.compute.stems import separate

    return track.shared(
        SEPARATE_KEY,
        lambda: separate(
            track.y, track.cfg.sr, backend=settings.stems, **separation_options(settings)
        ),
    )


def _stem_libraries(settings: AudioSettings | None) -> tuple[str, ...]:
    if (settings or _DEFAULT).stems == "openunmix":
        return (*BASE_LIBRARIES, "torch", "torchaudio", "openunmix")
    return BASE_LIBRARIES


def _stem_check(settings: AudioSettings) -> str | None:
    if settings.stems not in STEM_CHOICES:
        return f"unknown stem backend {settings.stems!r}; choose from {', '.join(STEM_CHOICES)}"
    if settings.stems == "none":
        return "needs a stem backend, but --stems is none"
    return None


class StemFeaturesFamily(AudioFamily):
    """onset_env, MFCC and onset peaks of each of the four stems."""

    name = "stems"

    def arrays(
        self, cfg: AudioFeatureConfig, settings: AudioSettings | None = None
    ) -> list[ArraySpec]:
        backend = (settings or _DEFAULT).stems
        specs = []
        for stem in STEM_NAMES:
            common = {"stem": stem, "backend": backend}
            specs += [
                ArraySpec(
                    f"stems/{stem}/onset_env",
                    (),
                    np.float32,
                    {**common, "recipe": "librosa.onset.onset_strength"},
                ),
                ArraySpec(
                    f"stems/{stem}/mfcc",
                    (cfg.n_mfcc,),
                    np.float32,
                    {**common, "recipe": "librosa.feature.mfcc"},
                ),
                ArraySpec(
                    f"stems/{stem}/onset_peaks",
                    (),
                    np.uint8,
                    {**common, "recipe": "librosa.onset.onset_detect on onset_env"},
                ),
            ]
        return specs

    def compute_track(
        self, track: TrackAudio, settings: AudioSettings | None = None
    ) -> dict[str, np.ndarray]:
        from dancedata.compute.stem_features import all_stem_features

        cfg = track.cfg
        features = all_stem_features(
            track_stems(track, settings or _DEFAULT),
            cfg.sr,
            hop_length=cfg.hop_length,
            n_fft=cfg.n_fft,
            n_mfcc=cfg.n_mfcc,
        )
        return {
            f"stems/{stem}/{name}": values
            for stem, by_name in features.items()
            for name, values in by_name.items()
        }

    def config(self, settings: AudioSettings | None = None) -> dict[str, Any]:
        return {
            "stem_backend": stem_backend_config(settings or _DEFAULT),
            "features": list(STEM_FEATURE_NAMES),
        }

    def group_attrs(
        self, cfg: AudioFeatureConfig, settings: AudioSettings | None = None
    ) -> dict[str, dict[str, Any]]:
        settings = settings or _DEFAULT
        return {
            "stems": {
                "backend": settings.stems,
                "backend_config": stem_backend_config(settings),
                "stems": list(STEM_NAMES),
                "features": list(STEM_FEATURE_NAMES),
            }
        }

    def check(self, settings: AudioSettings) -> str | None:
        return _stem_check(settings)

    def libraries(self, settings: AudioSettings | None = None) -> tuple[str, ...]:
        return _stem_libraries(settings)


class NmfdDrumsFamily(AudioFamily):
    """Kick, snare and hi-hat NMFD activations of the drums stem, (A, 3)."""

    name = "nmfd"

    def arrays(
        self, cfg: AudioFeatureConfig, settings: AudioSettings | None = None
    ) -> list[ArraySpec]:
        settings = settings or _DEFAULT
        attrs = {
            "components": list(NMFD_COMPONENTS),
            "stem": "drums",
            "backend": settings.stems,
            "template_frames": settings.nmfd_template_frames,
            "iterations": settings.nmfd_iterations,
            "divergence": NMFD_DIVERGENCE,
            "recipe": "dancedata.compute.nmfd.nmfd_drums (KL multiplicative updates)",
        }
        return [ArraySpec("nmfd_drums", (len(NMFD_COMPONENTS),), np.float32, attrs)]

    def compute_track(
        self, track: TrackAudio, settings: AudioSettings | None = None
    ) -> dict[str, np.ndarray]:
        from dancedata.compute.nmfd import nmfd_drums

        settings = settings or _DEFAULT
        cfg = track.cfg
        drums = track_stems(track, settings)["drums"]
        activations = nmfd_drums(
            drums,
            cfg.sr,
            hop_length=cfg.hop_length,
            n_fft=cfg.n_fft,
            n_lags=settings.nmfd_template_frames,
            n_iter=settings.nmfd_iterations,
        )
        return {"nmfd_drums": activations}

    def config(self, settings: AudioSettings | None = None) -> dict[str, Any]:
        settings = settings or _DEFAULT
        return {
            "stem_backend": stem_backend_config(settings),
            "components": list(NMFD_COMPONENTS),
            "template_frames": settings.nmfd_template_frames,
            "iterations": settings.nmfd_iterations,
            "divergence": NMFD_DIVERGENCE,
        }

    def check(self, settings: AudioSettings) -> str | None:
        problem = _stem_check(settings)
        if problem:
            return problem
        if settings.nmfd_iterations < 1 or settings.nmfd_template_frames < 1:
            return "NMFD iterations and template frames must be at least 1"
        return None

    def libraries(self, settings: AudioSettings | None = None) -> tuple[str, ...]:
        return _stem_libraries(settings)
