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
from dancedata.compute.stems import STEM_BACKENDS, STEM_NAMES
from dancedata.featurize.families.audio_base import (
    BASE_LIBRARIES,
    STEM_CHOICES,
    ArraySpec,
    AudioFamily,
    AudioSettings,
    TrackAudio,
)
from dancedata.featurize.family import register_family
from dancedata.store.checksums import sha256_file

SEPARATE_KEY = "separate"
DRUMS_MAG_KEY = "drums_stft"
# How the openunmix backend is fed and how its stems reach the feature rate (recorded).
OPENUNMIX_SEPARATION: dict[str, str] = {
    "input": "the music file's own samples: its channels and its sample rate",
    "rate": "the model's (separator.json sample_rate; 44100 Hz for umxhq/umxl); a file at "
    "another rate is resampled to it with librosa soxr_hq",
    "channels": "the file's own: mono duplicated to the model's 2, only the first 2 of more "
    "(as openunmix.utils.preprocess)",
    "chunking": "whole_track when the estimated peak memory fits memory_mb (and chunk_seconds is "
    "null), else overlap_add_crossfade: chunks separated alone, starting on the whole track's "
    "Wiener windows (wiener_win_len x hop samples) when long enough, linear cross-fades over "
    "overlap_seconds",
    "output": "per stem the mean of its channels, resampled from the model rate to the feature "
    "rate with config.audio.res_type and fitted to the mix's length",
}
_DEFAULT = AudioSettings()


@functools.lru_cache(maxsize=32)
def _file_sha256(path: str, size: int, mtime_ns: int) -> str:
    return sha256_file(path)


def weights_checksums(model: str, weights_dir: str | None) -> dict[str, dict[str, str]]:
    """{stem: {"file": name, "sha256": hex}} of the OpenUnmix weight files featurize would load
    (see :func:`dancedata.io.openunmix_weights.find_weights`; hashed once per process)."""
    from dancedata.io.openunmix_weights import find_weights

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
    if settings.stem_backend.needs_weights:
        return {
            "model": settings.stems_model,
            "weights_dir": settings.stems_weights,
            "device": settings.stems_device,
            "memory_mb": float(settings.stems_memory_mb),
        }
    return {}


# Revision of the offline separation's arithmetic, recorded in the stem families' config (so in
# the manifest, the fingerprint and the feature-cache key): features cached by an older
# revision are recomputed. 2: float32 masks and inverse STFTs (outputs within float32
# rounding of revision 1, see tests/featurize/test_audio_reference.py).
OFFLINE_ALGORITHM = 2


def algorithm_config(settings: AudioSettings) -> dict[str, Any]:
    """``{"offline_algorithm": OFFLINE_ALGORITHM}`` for the offline backend (the package's own
    arithmetic), else nothing (a backend with weights is recorded by their sha256)."""
    chosen = settings.stem_backend
    return {} if chosen.needs_weights else {f"{chosen.name}_algorithm": OFFLINE_ALGORITHM}


def stem_backend_config(settings: AudioSettings) -> dict[str, Any]:
    """Every setting of the stem backend (see :func:`dancedata.compute.stems.backend_config`);
    for ``openunmix`` the weights folder is replaced by the weight files' names and sha256."""
    from dancedata.compute.stems import backend_config

    config = backend_config(settings.stem_backend, **separation_options(settings))
    if settings.stem_backend.needs_weights:
        from dancedata.io import openunmix_weights as umx

        config.pop("weights_dir", None)
        config["weights"] = weights_checksums(settings.stems_model, settings.stems_weights)
        if umx.is_model_folder(settings.stems_weights):
            config["model"] = "openunmix model folder"
            config["separator_json"] = umx.read_separator_json(settings.stems_weights)  # type: ignore[arg-type]
        config["separation"] = OPENUNMIX_SEPARATION
    return config


def track_stems(track: TrackAudio, settings: AudioSettings) -> dict[str, np.ndarray]:
    """The track's four stems (mono float32 at ``cfg.sr``, the mix's length), separated once per
    track. ``openunmix`` separates the file's own samples (its rate, its channels; see
    :func:`openunmix_stems`); ``offline`` the feature-rate mono mix."""
    from dancedata.compute.stems import separate

    if settings.stem_backend.needs_weights:
        return track.shared(SEPARATE_KEY, lambda: openunmix_stems(track, settings))
    options = separation_options(settings)
    return track.shared(
        SEPARATE_KEY,
        lambda: separate(
            track.y,
            track.cfg.sr,
            backend=settings.stem_backend,
            stft=track.stft() if _stft_agrees(track.cfg, settings) else None,
            **options,
        ),
    )


def _stft_agrees(cfg: AudioFeatureConfig, settings: AudioSettings) -> bool:
    """Whether the offline backend's STFT is the track's shared one (same n_fft and hop)."""
    chosen = settings.stem_backend
    config = chosen.config(**separation_options(settings))
    return chosen.takes_stft and (config["n_fft"], config["hop_length"]) == (
        cfg.n_fft,
        cfg.hop_length,
    )


def drums_magnitude(track: TrackAudio, settings: AudioSettings) -> np.ndarray:
    """|STFT| of the drums stem (``cfg.n_fft``, ``cfg.hop_length``), computed once per track:
    the drums' stem features and the NMFD both start from it (its time counts for the first of
    them)."""
    from dancedata.compute.stem_features import stem_magnitude

    cfg = track.cfg
    return track.shared(
        DRUMS_MAG_KEY,
        lambda: stem_magnitude(track_stems(track, settings)["drums"], cfg.hop_length, cfg.n_fft),
        timed=False,
    )


def openunmix_stems(track: TrackAudio, settings: AudioSettings) -> dict[str, np.ndarray]:
    """OpenUnmix stems of the track's file as ``openunmix`` separates it: every channel at the
    file's rate (resampled to the model's 44.1 kHz only when it differs), then per stem the
    channel mean resampled to the feature rate with the featurize resampler (``cfg.res_type``,
    as the mix) and fitted to the mix's length. The span decoded is the mix's (``span_s``)."""
    from dancedata.featurize.stem_separation import separate_channels

    native = decode_native_checked(track.path, track.sha256, track.span_s)
    stems, plan = separate_channels(
        native.samples,
        native.sr,
        out_sr=track.cfg.sr,
        out_length=int(track.y.shape[-1]),
        res_type=track.cfg.res_type,
        **separation_options(settings),
    )
    if plan["method"] != "whole_track":
        import warnings

        warnings.warn(
            f"{track.path}: OpenUnmix separated in {plan['chunk_seconds']:g} s chunks "
            f"(whole track estimated at {plan['estimated_mb']:g} MB > memory_mb "
            f"{plan['memory_mb']:g})",
            RuntimeWarning,
            stacklevel=2,
        )
    return stems


def decode_native_checked(path: str, sha256: str | None, max_seconds: float | None) -> Any:
    """:func:`dancedata.io.audio_native.decode_native` of ``path`` from the very bytes hashed
    here, whose sha256 must equal ``sha256`` (the verified one) when given."""
    from dancedata.errors import InputError
    from dancedata.io.audio_native import decode_native
    from dancedata.io.music_file import sha256_of_handle

    try:
        handle = open(path, "rb")  # noqa: SIM115 - closed below, after the decode
    except OSError as exc:
        raise InputError(f"cannot open music file: {exc.strerror or exc}", path) from None
    with handle:
        actual = sha256_of_handle(handle)
        if sha256 and actual != sha256:
            raise InputError(
                f"changed since ingest (sha256 {actual[:12]}… on disk, {sha256[:12]}… "
                "verified); run ingest again, or pass --accept-changed-music to featurize",
                path,
            )
        return decode_native(handle, path=path, max_seconds=max_seconds)


def _stem_libraries(settings: AudioSettings | None) -> tuple[str, ...]:
    settings = settings or _DEFAULT
    if settings.stems not in STEM_BACKENDS:  # none or unknown: check() says so
        return BASE_LIBRARIES
    return (*BASE_LIBRARIES, *settings.stem_backend.libraries)


def _stem_check(settings: AudioSettings) -> str | None:
    if settings.stems not in STEM_CHOICES:
        return f"unknown stem backend {settings.stems!r}; choose from {', '.join(STEM_CHOICES)}"
    if settings.stems == "none":
        return "needs a stem backend, but --stems is none"
    return None


_STEM_ATTRS = ("backend", "stem")


@register_family("stems")
class StemFeaturesFamily(AudioFamily):
    """onset_env, MFCC and onset peaks of each of the four stems."""

    outputs = tuple(
        spec
        for stem in STEM_NAMES
        for spec in (
            ArraySpec(f"stems/{stem}/onset_env", (), np.float32, required_attrs=_STEM_ATTRS),
            ArraySpec(f"stems/{stem}/mfcc", (20,), np.float32, required_attrs=_STEM_ATTRS),
            ArraySpec(f"stems/{stem}/onset_peaks", (), np.uint8, required_attrs=_STEM_ATTRS),
        )
    )

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
        settings = settings or _DEFAULT
        features = all_stem_features(
            track_stems(track, settings),
            cfg.sr,
            hop_length=cfg.hop_length,
            n_fft=cfg.n_fft,
            n_mfcc=cfg.n_mfcc,
            mags={"drums": drums_magnitude(track, settings)},
        )
        return {
            f"stems/{stem}/{name}": values
            for stem, by_name in features.items()
            for name, values in by_name.items()
        }

    def config(self, settings: AudioSettings | None = None) -> dict[str, Any]:
        settings = settings or _DEFAULT
        return {
            "stem_backend": stem_backend_config(settings),
            **algorithm_config(settings),
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


@register_family("nmfd")
class NmfdDrumsFamily(AudioFamily):
    """Kick, snare and hi-hat NMFD activations of the drums stem, (A, 3)."""

    outputs = (
        ArraySpec(
            "nmfd_drums",
            (len(NMFD_COMPONENTS),),
            np.float32,
            required_attrs=("components", "backend"),
        ),
    )

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
            mag=drums_magnitude(track, settings),
        )
        return {"nmfd_drums": activations}

    def config(self, settings: AudioSettings | None = None) -> dict[str, Any]:
        settings = settings or _DEFAULT
        return {
            "stem_backend": stem_backend_config(settings),
            **algorithm_config(settings),
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
