"""One track through the audio families, with the feature cache in front of each family.

For every requested family: look its arrays up in the feature cache (key: the track's sha256,
the decoded span when it is shorter than the track, the family's config, the FACT config, the
dancedata and library versions); on a miss compute them through the track's shared context
(decode once, separate once) and save them. A track whose families all hit the cache is never
decoded. The sha256 in the key is the verified hash of the file's content (see
:mod:`dancedata.featurize.music_inputs`): featurize checks it against the file before planning,
and the decode hashes the bytes it decodes and refuses them if they differ, so an entry is only
ever saved under the hash of the content it was computed from.

:func:`compute_track_features` also measures what it did, per track: wall seconds of the decode,
of each shared step (``separate``: the stems) and of each family (its own work, shared steps
excluded), the cache hits and misses, and which track this is in its process (the first track
of a process pays for imports and numba compilation: ~3 s for the numba kernel librosa.beat
compiles at import without caching it; worker processes live for the whole run, so that is paid
once per worker, not once per track).
"""

from __future__ import annotations

import time
from typing import Any

import numpy as np

from dancedata._version import __version__
from dancedata.compute.audio_features import AudioFeatureConfig
from dancedata.featurize.families.audio_base import AudioSettings, TrackAudio
from dancedata.featurize.family import registered
from dancedata.featurize.feature_cache import FeatureCache, cache_key, library_versions

_TRACKS_IN_PROCESS = 0


def family_cache_key(
    name: str,
    settings: AudioSettings,
    cfg: AudioFeatureConfig,
    audio_sha256: str,
    bpm: float | None = None,
    span_s: float | None = None,
) -> str:
    """The feature-cache key of family ``name`` on the track with content ``audio_sha256``
    (and tempo ``bpm``, for families that use it), decoded whole or, with ``span_s``, only its
    first ``span_s`` seconds."""
    family = registered("audio")[name]
    track: dict[str, float | None] = {"bpm": bpm} if family.uses_bpm else {}
    if span_s is not None:
        track["decoded_s"] = round(float(span_s), 6)
    return cache_key(
        audio_sha256,
        name,
        family.config(settings),
        cfg.as_dict(),
        __version__,
        library_versions(family.libraries(settings)),
        track=track or None,
    )


def compute_track_features(
    families: tuple[str, ...] | list[str],
    settings: AudioSettings,
    cfg: AudioFeatureConfig,
    path: str,
    bpm: float | None,
    *,
    audio_sha256: str | None = None,
    music_id: str | None = None,
    cache_dir: str | None = None,
    span_s: float | None = None,
    partial: bool = False,
) -> tuple[dict[str, np.ndarray], dict[str, Any]]:
    """Arrays of every family in ``families`` for the track at ``path`` (untrimmed), and the
    run's statistics. ``cache_dir`` None (or no ``audio_sha256``) bypasses the cache. At most
    the first ``span_s`` seconds are decoded (None: all); ``partial`` says that is fewer than
    the whole track, which then keys the cache."""
    global _TRACKS_IN_PROCESS
    order = _TRACKS_IN_PROCESS
    _TRACKS_IN_PROCESS += 1
    start = time.perf_counter()
    cache = FeatureCache(cache_dir) if cache_dir and audio_sha256 else None
    track = TrackAudio(path, bpm, cfg, sha256=audio_sha256, span_s=span_s)
    key_span = span_s if partial else None
    features: dict[str, np.ndarray] = {}
    seconds: dict[str, float] = {}
    hits = misses = 0
    registry = registered("audio")
    for name in families:
        family = registry[name]
        specs = family.arrays(cfg, settings)
        key = family_cache_key(name, settings, cfg, audio_sha256, bpm, key_span) if cache else None
        if cache is not None and key is not None:
            expected = {s.path: (tuple(s.row_shape), s.dtype) for s in specs}
            cached = cache.load(key, expected)
            if cached is not None:
                features.update(cached)
                hits += 1
                continue
        misses += 1
        shared_before = track.shared_seconds()
        began = time.perf_counter()
        arrays = family.compute_track(track, settings)
        own = time.perf_counter() - began - (track.shared_seconds() - shared_before)
        seconds[name] = round(own, 4)
        arrays = {s.path: np.asarray(arrays[s.path], dtype=s.dtype) for s in specs}
        features.update(arrays)
        if cache is not None and key is not None:
            meta = {
                "family": name,
                "config": family.config(settings),
                "audio_config": cfg.as_dict(),
                "audio_sha256": audio_sha256,
                "bpm": bpm if family.uses_bpm else None,
                "decoded_s": track.decoded_s,
                "music_id": music_id,
                "source": str(path),
                "dancedata_version": __version__,
            }
            cache.save(key, arrays, meta)
    seconds.update({k: round(v, 4) for k, v in track.timings.items()})
    stats: dict[str, Any] = {
        "cache_hits": hits,
        "cache_misses": misses,
        "seconds": seconds,
        "track_seconds": round(time.perf_counter() - start, 4),
        "track_in_process": order,
    }
    if track.decoded:
        stats["samples"] = int(track.y.shape[0])
        stats["decoded_s"] = track.decoded_s
    return features, stats


def audio_task_counts(results: list[dict[str, Any]]) -> dict[str, Any]:
    """Manifest counts from the tracks' task results: feature-cache hits and misses (one per
    track and family), wall seconds per step summed over tracks (``decode``, ``separate``,
    each family's own work), and per-track seconds of the first track each process ran (which
    pays for imports and numba compilation) against the mean of the later ones."""
    seconds: dict[str, float] = {}
    first: list[float] = []
    later: list[float] = []
    for result in results:
        for key, value in (result.get("seconds") or {}).items():
            seconds[key] = seconds.get(key, 0.0) + float(value)
        if "track_seconds" in result:
            bucket = first if result.get("track_in_process") == 0 else later
            bucket.append(float(result["track_seconds"]))
    return {
        "audio_cache_hits": sum(int(r.get("cache_hits", 0)) for r in results),
        "audio_cache_misses": sum(int(r.get("cache_misses", 0)) for r in results),
        "audio_seconds": {key: round(value, 3) for key, value in sorted(seconds.items())},
        "audio_track_seconds": {
            "first_in_process": [round(v, 3) for v in first],
            "later_mean": round(sum(later) / len(later), 3) if later else None,
            "later_max": round(max(later), 3) if later else None,
        },
    }
