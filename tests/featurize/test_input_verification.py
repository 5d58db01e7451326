"""Music inputs are verified before use: featurize checks each file against the size, mtime and
sha256 recorded at ingest, refuses a changed file with one line naming it (or re-hashes it on
``--accept-changed-music``), caches features only under the hash of the content it decoded, and
finds files by the absolute paths ingest recorded, from any working directory."""

from __future__ import annotations

import hashlib
import os
import shutil
import subprocess
import sys
from pathlib import Path

import librosa
import numpy as np
import pytest
import soundfile as sf

from dancedata.errors import InputError
from dancedata.featurize.families.audio_base import AudioSettings
from dancedata.featurize.feature_cache import FeatureCache
from dancedata.featurize.featurize import FeaturizeOptions, featurize
from dancedata.ingest.aist import AistIngestOptions, ingest_aist
from dancedata.store.layout import StoreLayout
from dancedata.store.reader import _VersionReader
from dancedata.synth.aist import synth_aist
from tests.helpers import REPO

SR = 30720  # AIST++: 60 fps × 512


def fact_only(**options) -> FeaturizeOptions:
    return FeaturizeOptions(
        audio_settings=AudioSettings(stems="none"), representations=["rotmat"], **options
    )


def cli(*args: str, cwd: Path, check: bool = True) -> subprocess.CompletedProcess:
    """``dancedata ARGS`` run from ``cwd`` (this checkout on the import path)."""
    env = {**os.environ, "PYTHONPATH": str(REPO)}
    proc = subprocess.run(
        [sys.executable, "-m", "dancedata.cli", *args],
        cwd=cwd,
        env=env,
        capture_output=True,
        text=True,
        timeout=600,
    )
    if check:
        assert proc.returncode == 0, proc.stderr
    return proc


def sha256(path: Path) -> str:
    return hashlib.sha256(path.read_bytes()).hexdigest()


def onset_env(path: Path) -> np.ndarray:
    y, _ = librosa.load(path, sr=SR)
    return librosa.onset.onset_strength(y=y, sr=SR, hop_length=512)


def rewrite_same_size(path: Path) -> None:
    """New samples (reversed, halved) in the same format: same size, other content."""
    info = sf.info(path)
    y, sr = sf.read(path, dtype="float32")
    sf.write(path, 0.5 * y[::-1], sr, subtype=info.subtype, format=info.format)


@pytest.fixture(scope="module")
def raw(tmp_path_factory) -> Path:
    root = tmp_path_factory.mktemp("verify_raw")
    synth_aist(root, n_sequences=2, seed=11)
    return root


@pytest.fixture
def fresh(raw: Path, tmp_path: Path) -> dict[str, Path]:
    """A private copy of the raw folder, ingested into a store: tests change its music."""
    copy = tmp_path / "raw"
    shutil.copytree(raw, copy)
    store = tmp_path / "store"
    ingest_aist(store, copy, AistIngestOptions())
    music = _VersionReader(store).table("music").to_pylist()[0]
    return {"raw": copy, "store": store, "music": Path(music["path"]), "row": music}


def versions(store: Path) -> list[str]:
    return sorted(p.name for p in (store / "versions").iterdir())


# ----------------------------------------------------------------------------- paths, stamps


@pytest.mark.slow
def test_relative_inputs_are_recorded_absolute_and_found_from_elsewhere(
    raw: Path, tmp_path: Path
) -> None:
    shutil.copytree(raw, tmp_path / "raw")
    cli("ingest", "aist", "raw", "--store", "store", "-q", cwd=tmp_path)
    store = tmp_path / "store"
    for row in _VersionReader(store).table("music").to_pylist():
        path = Path(row["path"])
        assert path.is_absolute() and path.parent == (tmp_path / "raw" / "wav").resolve()
        stat = path.stat()
        assert (row["size_bytes"], row["mtime_ns"]) == (stat.st_size, stat.st_mtime_ns)
        assert row["sha256"] == sha256(path)
    elsewhere = tmp_path / "elsewhere"
    elsewhere.mkdir()
    cli("featurize", str(store), "--stems", "none", "-q", cwd=elsewhere)
    assert _VersionReader(store).version == "v2"


@pytest.mark.slow
def test_bvh_music_given_relative_is_recorded_absolute(tmp_path: Path) -> None:
    from tests.featurize.test_audio_limits import clicks, dance

    dance(tmp_path / "d.bvh", 3.0)
    clicks(tmp_path / "song.flac", 4.0)
    cli(
        "ingest",
        "bvh",
        "d.bvh",
        "--store",
        "s",
        "--music",
        "song.flac",
        "--bpm",
        "120",
        "-q",
        cwd=tmp_path,
    )
    row = _VersionReader(tmp_path / "s").table("music").to_pylist()[0]
    assert row["path"] == str((tmp_path / "song.flac").resolve())
    assert row["size_bytes"] == (tmp_path / "song.flac").stat().st_size


# ----------------------------------------------------------------------------- changed files


@pytest.mark.slow
def test_changed_music_is_refused_with_one_line_naming_it(fresh: dict[str, Path]) -> None:
    music, store = fresh["music"], fresh["store"]
    rewrite_same_size(music)
    with pytest.raises(InputError, match=r"changed since ingest .*--accept-changed-music") as info:
        featurize(store, fact_only())
    assert info.value.path == str(music)
    proc = cli("featurize", str(store), "-q", cwd=store.parent, check=False)
    lines = [line for line in proc.stderr.splitlines() if line.strip()]
    assert proc.returncode == 1 and len(lines) == 1 and "Traceback" not in proc.stderr
    assert lines[0].startswith(f"error: {music}: changed since ingest (sha256 {sha256(music)[:12]}")
    assert versions(store) == ["v1"]  # nothing written, no temporary folder left


def test_missing_music_is_refused_naming_it(fresh: dict[str, Path]) -> None:
    fresh["music"].unlink()
    with pytest.raises(InputError, match="music file not found") as info:
        featurize(fresh["store"], fact_only())
    assert info.value.path == str(fresh["music"])


def test_touched_music_with_the_same_content_passes_and_gets_its_new_stamp(
    fresh: dict[str, Path],
) -> None:
    music, store = fresh["music"], fresh["store"]
    later = music.stat().st_mtime_ns + 5_000_000_000
    os.utime(music, ns=(later, later))
    result = featurize(store, fact_only())
    row = _VersionReader(store, result.version).table("music").to_pylist()[0]
    assert row["mtime_ns"] == later and row["sha256"] == fresh["row"]["sha256"]
    assert "music_accepted_changes" not in StoreLayout(store).read_manifest("v2")["config"]


def test_new_content_behind_the_old_size_and_mtime_is_caught_when_decoded(
    fresh: dict[str, Path], tmp_path: Path
) -> None:
    """The stamp is only the fast path: the decode hashes the bytes it decodes."""
    music = fresh["music"]
    stat = music.stat()
    rewrite_same_size(music)
    os.utime(music, ns=(stat.st_atime_ns, stat.st_mtime_ns))
    assert music.stat().st_size == stat.st_size
    with pytest.raises(InputError, match="changed since ingest") as info:
        featurize(fresh["store"], fact_only(cache_dir=str(tmp_path / "cache")))
    assert info.value.path == str(music)
    assert versions(fresh["store"]) == ["v1"]


def test_accept_changed_music_rehashes_and_records_it(
    fresh: dict[str, Path], tmp_path: Path
) -> None:
    music, store = fresh["music"], fresh["store"]
    y, sr = sf.read(music, dtype="float32")
    sf.write(music, np.concatenate([y, y[: sr * 2]]), sr, subtype=sf.info(music).subtype)
    result = featurize(store, fact_only(accept_changed_music=True, cache_dir=str(tmp_path / "c")))
    reader = _VersionReader(store, result.version)
    row = next(r for r in reader.table("music").to_pylist() if r["music_id"] == music.stem)
    stat = music.stat()
    assert row["sha256"] == sha256(music) != fresh["row"]["sha256"]
    assert (row["size_bytes"], row["mtime_ns"]) == (stat.st_size, stat.st_mtime_ns)
    assert row["n_samples"] == fresh["row"]["n_samples"] + 2 * sr
    config = reader.manifest["config"]
    assert config["music_accepted_changes"] == {music.stem: sha256(music)}
    stored = np.asarray(reader.array("audio/onset_env")[row["frame_start"] : row["frame_stop"]])
    np.testing.assert_allclose(stored, onset_env(music), rtol=1e-5, atol=1e-5)
    # The changed content had not been featurized: an unchanged run would have been done.
    assert result.created


@pytest.mark.slow
def test_cache_never_holds_new_content_under_the_old_hash(
    fresh: dict[str, Path], tmp_path: Path
) -> None:
    """Store A's music changes and is accepted; store B holds the old content. B's features
    are those of the old content: A's run saved nothing under the old hash."""
    music = fresh["music"]
    old_copy = tmp_path / "old_content" / "wav"
    shutil.copytree(music.parent, old_copy)
    old_sha = fresh["row"]["sha256"]
    cache_dir = tmp_path / "cache"
    rewrite_same_size(music)
    featurize(fresh["store"], fact_only(accept_changed_music=True, cache_dir=str(cache_dir)))
    saved = [e.meta for e in FeatureCache(cache_dir).entries()]
    assert {m["audio_sha256"] for m in saved if m["music_id"] == music.stem} == {sha256(music)}

    other = tmp_path / "store_b"
    ingest_aist(other, fresh["raw"], AistIngestOptions(music_dir=old_copy))
    result = featurize(other, fact_only(cache_dir=str(cache_dir)))
    reader = _VersionReader(other, result.version)
    row = next(r for r in reader.table("music").to_pylist() if r["music_id"] == music.stem)
    assert row["sha256"] == old_sha
    stored = np.asarray(reader.array("audio/onset_env")[row["frame_start"] : row["frame_stop"]])
    np.testing.assert_allclose(stored, onset_env(old_copy / music.name), rtol=1e-5, atol=1e-5)
    assert reader.manifest["counts"]["audio_cache_misses"] >= 1  # the old content: computed
