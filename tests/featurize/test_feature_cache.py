"""The per-track feature cache: keys, atomic writes, damaged entries, clearing, the CLI, and
featurize reusing cached features across runs, versions and stores (counted in the manifest)."""

from __future__ import annotations

import hashlib
import json
import multiprocessing
import os
import time
from pathlib import Path

import numpy as np
import pytest

import dancedata
from dancedata.featurize.families.audio import AudioSettings
from dancedata.featurize.feature_cache import (
    ENV_VAR,
    FeatureCache,
    cache_key,
    default_cache_dir,
    library_versions,
)
from dancedata.featurize.featurize import FeaturizeOptions, featurize
from dancedata.ingest.aist import AistIngestOptions, ingest_aist
from dancedata.synth.aist import synth_aist
from tests.helpers import run_cli

SPEC = {"onset_env": ((), np.float32), "mfcc": ((20,), np.float32)}


def _arrays(n: int = 50, seed: int = 0) -> dict[str, np.ndarray]:
    rng = np.random.default_rng(seed)
    return {
        "onset_env": rng.random(n).astype(np.float32),
        "mfcc": rng.standard_normal((n, 20)).astype(np.float32),
    }


def _key(**change: object) -> str:
    parts = {
        "audio_sha256": "a" * 64,
        "family": "fact",
        "family_config": {},
        "audio_config": {"fps": 60.0, "hop_length": 512},
        "dancedata_version": "0.1.0",
        "libraries": {"librosa": "0.11.0"},
    }
    parts.update(change)
    return cache_key(**parts)  # type: ignore[arg-type]


def test_tests_use_a_temporary_cache(feature_cache_dir) -> None:
    assert os.environ[ENV_VAR] == str(feature_cache_dir)
    assert default_cache_dir() == feature_cache_dir
    assert not str(default_cache_dir()).startswith(str(Path.home() / ".cache"))


def test_key_changes_with_every_part() -> None:
    base = _key()
    variants = [
        _key(audio_sha256="b" * 64),
        _key(family="stems"),
        _key(family_config={"stem_backend": {"backend": "openunmix"}}),
        _key(audio_config={"fps": 30.0, "hop_length": 512}),
        _key(dancedata_version="0.2.0"),
        _key(libraries={"librosa": "0.10.2"}),
        _key(track={"bpm": 120.0}),
    ]
    assert len({base, *variants}) == 8
    assert _key() == base  # deterministic, key order irrelevant
    assert library_versions(["numpy", "surely-not-installed-xyz"]) == {
        "numpy": np.__version__,
        "surely-not-installed-xyz": "absent",
    }


def test_save_load_round_trip_and_misses(tmp_path) -> None:
    cache = FeatureCache(tmp_path / "c")
    key = _key()
    assert cache.load(key, SPEC) is None  # empty cache
    arrays = _arrays()
    assert cache.save(key, arrays, {"family": "fact", "music_id": "mBR0"})
    got = cache.load(key, SPEC)
    assert got is not None
    for name in SPEC:
        np.testing.assert_array_equal(got[name], arrays[name])
        assert got[name].dtype == arrays[name].dtype
    assert not list(cache.root.glob("??/.tmp-*"))  # nothing left behind by the writer
    (entry,) = cache.entries()
    assert (entry.family, entry.source, entry.key) == ("fact", "mBR0", key)


@pytest.mark.parametrize(
    "expected",
    [
        {"onset_env": ((), np.float32), "mfcc": ((13,), np.float32)},  # other row shape
        {"onset_env": ((), np.float64), "mfcc": ((20,), np.float32)},  # other dtype
        {"onset_env": ((), np.float32), "chroma": ((12,), np.float32)},  # missing array
    ],
)
def test_entries_that_disagree_with_the_family_are_missed_and_removed(tmp_path, expected) -> None:
    cache = FeatureCache(tmp_path)
    key = _key()
    cache.save(key, _arrays(), {"family": "fact"})
    assert cache.load(key, expected) is None
    assert not cache.path(key).exists()


def test_damaged_entries_are_missed_and_removed(tmp_path) -> None:
    cache = FeatureCache(tmp_path)
    key = _key()
    cache.save(key, _arrays(), {"family": "fact"})
    data = cache.path(key).read_bytes()
    cache.path(key).write_bytes(data[: len(data) // 2])  # truncated
    assert cache.load(key, SPEC) is None and not cache.path(key).exists()
    cache.save(key, _arrays(), {"family": "fact"})
    other = _key(family="stems")
    cache.path(other).parent.mkdir(parents=True, exist_ok=True)
    os.replace(cache.path(key), cache.path(other))
    assert cache.load(other, SPEC) is None  # header names another key


def test_unwritable_cache_never_fails(tmp_path) -> None:
    blocker = tmp_path / "file"
    blocker.write_text("not a folder")
    cache = FeatureCache(blocker / "cache")
    assert cache.save(_key(), _arrays(), {}) is False
    assert cache.load(_key(), SPEC) is None


def _hammer(root: str, seed: int, rounds: int) -> int:
    """Write the same key ``rounds`` times and read it back in between; count bad reads."""
    cache = FeatureCache(root)
    key = _key()
    bad = 0
    for _ in range(rounds):
        cache.save(key, _arrays(n=4000, seed=0), {"family": "fact", "writer": seed})
        got = cache.load(key, SPEC)
        if got is not None and not np.array_equal(got["mfcc"], _arrays(n=4000)["mfcc"]):
            bad += 1
    return bad


@pytest.mark.slow
def test_parallel_writers_of_one_entry_are_safe(tmp_path) -> None:
    ctx = multiprocessing.get_context("spawn")
    with ctx.Pool(2) as pool:
        bad = pool.starmap(_hammer, [(str(tmp_path), s, 25) for s in range(2)])
    assert bad == [0, 0]
    cache = FeatureCache(tmp_path)
    assert cache.load(_key(), SPEC) is not None
    assert [p.name for p in tmp_path.glob("??/*")] == [cache.path(_key()).name]


def test_clear_all_older_than_and_stale_temp_files(tmp_path) -> None:
    cache = FeatureCache(tmp_path)
    old, fresh = _key(family="old"), _key(family="fresh")
    cache.save(old, _arrays(), {"family": "old"})
    cache.save(fresh, _arrays(), {"family": "fresh"})
    ten_days = time.time() - 10 * 86400
    os.utime(cache.path(old), (ten_days, ten_days))
    stale = cache.path(fresh).parent / ".tmp-dead-writer.npz"
    stale.write_bytes(b"partial")
    os.utime(stale, (ten_days, ten_days))
    report = cache.clear(older_than_days=5)
    assert (report.entries, report.temp_files) == (1, 1)
    assert report.bytes > 0
    assert [e.family for e in cache.entries()] == ["fresh"]
    cache.load(fresh, SPEC)  # a hit marks the entry used now
    assert cache.clear(older_than_days=0.5).entries == 0
    assert cache.clear().entries == 1 and cache.entries() == []
    assert list(tmp_path.iterdir()) == []  # empty shard folders go too


@pytest.mark.slow
def test_track_tempo_keys_only_the_families_that_use_it(tmp_path) -> None:
    """The FACT beats follow the music's known BPM, so a different BPM for the same file misses
    ``fact``; the stems do not depend on it and hit."""
    import soundfile as sf

    from dancedata.compute.audio_features import AudioFeatureConfig
    from dancedata.featurize.audio_track import compute_track_features
    from dancedata.synth.music import synth_dance_music

    path = tmp_path / "song.wav"
    sf.write(path, synth_dance_music(120.0, 3.0, sr=22050), 22050)
    sha = hashlib.sha256(path.read_bytes()).hexdigest()
    run = dict(
        families=["fact", "stems"],
        settings=AudioSettings(),
        cfg=AudioFeatureConfig(),
        path=str(path),
        audio_sha256=sha,
        cache_dir=str(tmp_path / "cache"),
    )
    first, stats = compute_track_features(bpm=120.0, **run)
    assert (stats["cache_hits"], stats["cache_misses"]) == (0, 2)
    again, stats = compute_track_features(bpm=120.0, **run)
    assert (stats["cache_hits"], stats["cache_misses"]) == (2, 0) and "samples" not in stats
    for name, values in first.items():
        np.testing.assert_array_equal(again[name], values)
    _, stats = compute_track_features(bpm=100.0, **run)
    assert (stats["cache_hits"], stats["cache_misses"]) == (1, 1)
    assert set(stats["seconds"]) == {"decode", "fact"}


def test_decoded_span_keys_the_cache_and_a_wrong_hash_is_never_saved(tmp_path) -> None:
    """A track decoded only in part is another entry than the whole track (and the whole
    track's key is the one it always was); bytes whose sha256 is not the given one are refused
    before anything is computed or saved under that hash."""
    import soundfile as sf

    from dancedata.compute.audio_features import AudioFeatureConfig
    from dancedata.errors import InputError
    from dancedata.featurize.audio_track import compute_track_features, family_cache_key
    from dancedata.synth.music import synth_dance_music

    cfg, settings = AudioFeatureConfig(), AudioSettings(stems="none")
    whole = family_cache_key("fact", settings, cfg, "a" * 64, 120.0)
    assert whole == family_cache_key("fact", settings, cfg, "a" * 64, 120.0, None)
    assert family_cache_key("fact", settings, cfg, "a" * 64, 120.0, 40.0) != whole
    assert family_cache_key("fact", settings, cfg, "a" * 64, 120.0, 41.0) != family_cache_key(
        "fact", settings, cfg, "a" * 64, 120.0, 40.0
    )

    path = tmp_path / "song.wav"
    sf.write(path, synth_dance_music(120.0, 6.0, sr=22050), 22050)
    sha = hashlib.sha256(path.read_bytes()).hexdigest()
    run = dict(
        families=["fact"],
        settings=settings,
        cfg=cfg,
        path=str(path),
        bpm=120.0,
        cache_dir=str(tmp_path / "cache"),
    )
    full, stats = compute_track_features(audio_sha256=sha, **run)
    part, stats = compute_track_features(audio_sha256=sha, span_s=3.0, partial=True, **run)
    assert stats["cache_misses"] == 1 and stats["decoded_s"] == pytest.approx(3.0)
    assert part["onset_env"].shape[0] == 1 + (3 * cfg.sr) // cfg.hop_length
    assert full["onset_env"].shape[0] > part["onset_env"].shape[0]
    _, stats = compute_track_features(audio_sha256=sha, span_s=3.0, partial=True, **run)
    assert stats["cache_hits"] == 1
    entries = len(FeatureCache(tmp_path / "cache").entries())
    with pytest.raises(InputError, match="changed since ingest"):
        compute_track_features(audio_sha256="b" * 64, **run)
    assert len(FeatureCache(tmp_path / "cache").entries()) == entries == 2


# -- featurize with the cache --------------------------------------------------------------------
@pytest.fixture(scope="module")
def raw(tmp_path_factory) -> Path:
    root = tmp_path_factory.mktemp("cache_raw")
    synth_aist(root, n_sequences=2, seed=11)
    return root


def _run(store: Path, cache_dir: Path, **options: object):
    return featurize(store, FeaturizeOptions(cache_dir=str(cache_dir), **options))  # type: ignore[arg-type]


@pytest.mark.slow
def test_featurize_reuses_cached_features(raw, tmp_path) -> None:
    cache_dir = tmp_path / "cache"
    store = tmp_path / "store"
    ingest_aist(store, raw, AistIngestOptions())
    first = _run(store, cache_dir)
    tracks = first.counts["music_tracks"]
    assert tracks == 2
    assert (first.counts["audio_cache_hits"], first.counts["audio_cache_misses"]) == (0, 6)
    assert {"decode", "separate", "fact", "stems", "nmfd"} <= set(first.counts["audio_seconds"])
    assert len(FeatureCache(cache_dir).entries()) == 3 * tracks

    # Another motion setting: a new version, and not one audio feature computed or decoded.
    second = _run(store, cache_dir, version="v1", representations=["rotmat"])
    assert second.created and second.version != first.version
    assert (second.counts["audio_cache_hits"], second.counts["audio_cache_misses"]) == (6, 0)
    assert second.counts["audio_seconds"] == {}
    a = dancedata.open_store(store, first.version)
    b = dancedata.open_store(store, second.version)
    for name in [n for n in a.array_names() if n.startswith("audio/")]:
        np.testing.assert_array_equal(a.zarr(name)[...], b.zarr(name)[...], err_msg=name)
    assert a.music.to_pylist() == b.music.to_pylist()

    # A second store holding the same music reuses them too.
    other = tmp_path / "other"
    ingest_aist(other, raw, AistIngestOptions())
    third = _run(other, cache_dir)
    assert (third.counts["audio_cache_hits"], third.counts["audio_cache_misses"]) == (6, 0)


@pytest.mark.slow
def test_config_change_misses_only_the_families_it_touches(raw, tmp_path) -> None:
    cache_dir = tmp_path / "cache"
    store = tmp_path / "store"
    ingest_aist(store, raw, AistIngestOptions())
    _run(store, cache_dir, motion=False)
    changed = _run(
        store,
        cache_dir,
        motion=False,
        version="v1",
        audio_settings=AudioSettings(nmfd_iterations=5),
    )
    assert changed.created
    assert (changed.counts["audio_cache_hits"], changed.counts["audio_cache_misses"]) == (4, 2)
    assert set(changed.counts["audio_seconds"]) >= {"nmfd", "separate"}
    assert "fact" not in changed.counts["audio_seconds"]
    bypass = _run(
        store, cache_dir, motion=False, version="v1", use_cache=False, audio_families=["fact"]
    )
    assert (bypass.counts["audio_cache_hits"], bypass.counts["audio_cache_misses"]) == (0, 2)
    assert len(FeatureCache(cache_dir).entries()) == 8  # 6 + the 2 new nmfd entries


@pytest.mark.slow
def test_cache_cli_lists_and_clears(raw, tmp_path) -> None:
    cache_dir = tmp_path / "cache"
    store = tmp_path / "store"
    ingest_aist(store, raw, AistIngestOptions())
    _run(store, cache_dir, motion=False, audio_families=["fact"])
    listed = json.loads(run_cli("cache", "list", "--cache-dir", str(cache_dir), "--json").stdout)
    assert listed["entries"] == 2 and listed["families"]["fact"]["entries"] == 2
    assert listed["bytes"] == sum(item["bytes"] for item in listed["items"]) > 0
    text = run_cli("cache", "list", "--cache-dir", str(cache_dir)).stdout
    assert "total: 2 entries" in text
    kept = run_cli("cache", "clear", "--older-than", "1", "--cache-dir", str(cache_dir)).stdout
    assert "removed 0 entries" in kept
    env = {ENV_VAR: str(cache_dir)}  # the environment variable names the default folder
    gone = json.loads(run_cli("cache", "clear", "--json", env=env).stdout)
    assert gone["removed"] == 2 and gone["cache_dir"] == str(cache_dir)
    assert FeatureCache(cache_dir).entries() == []


def test_library_versions_are_the_installed_ones_read_once_per_process():
    """The versions in cache keys and manifests are importlib.metadata's, and each is read once
    per process (a look-up scans site-packages; featurize asks per track and family)."""
    from importlib import metadata

    from dancedata._version import __version__, installed_version
    from dancedata.featurize.feature_cache import library_versions
    from dancedata.store.writer import library_versions as manifest_libraries

    names = ("numpy", "scipy", "librosa", "no-such-distribution-here")
    got = library_versions(names)
    assert got == {
        "numpy": metadata.version("numpy"),
        "scipy": metadata.version("scipy"),
        "librosa": metadata.version("librosa"),
        "no-such-distribution-here": "absent",
    }
    recorded = manifest_libraries()
    assert recorded.pop("dancedata") == __version__
    assert recorded == {n: metadata.version(n) for n in recorded}
    assert "zarr" in recorded and "pyarrow" in recorded
    hits = installed_version.cache_info().hits
    library_versions(names)
    assert installed_version.cache_info().hits == hits + len(names)
