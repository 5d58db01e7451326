"""checksums.json is recorded at commit; ``validate --deep`` re-hashes every file and names each
corrupted chunk, array and table, in every version that shares the damaged file by hard link."""

from __future__ import annotations

import json
import os
from pathlib import Path

import pytest

from dancedata.featurize.featurize import FeaturizeOptions, featurize
from dancedata.featurize.segment import SegmentOptions, segment
from dancedata.ingest.aist import AistIngestOptions, ingest_aist
from dancedata.store.checksums import sha256_file
from dancedata.store.integrity import CHECKSUMS_FILE, data_files, describe_file, load_record
from dancedata.store.validate import validate_store
from dancedata.synth.aist import synth_aist
from tests.helpers import run_cli


def _flip(path: Path, offset: int | None = None) -> None:
    """Invert one byte in place (the inode stays the same, as with real bit rot)."""
    data = bytearray(path.read_bytes())
    at = len(data) // 2 if offset is None else offset
    data[at] ^= 0xFF
    with open(path, "r+b") as handle:
        handle.write(data)


@pytest.fixture(scope="module")
def pristine(tmp_path_factory) -> Path:
    """v1 ingest, v2 motion-only featurize, v3 segment (no audio features: quick)."""
    root = tmp_path_factory.mktemp("integrity")
    synth_aist(root / "raw", n_sequences=3, seed=21)
    store = root / "store"
    ingest_aist(store, root / "raw", AistIngestOptions())
    featurize(store, FeaturizeOptions(audio=False))
    segment(store, SegmentOptions())
    return store


@pytest.fixture
def store(pristine, tmp_path) -> Path:
    """A private copy of the pristine store that keeps its hard links between versions."""
    copy = tmp_path / "store"
    subprocess_cp(pristine, copy)
    return copy


def subprocess_cp(src: Path, dst: Path) -> None:
    """Copy a store preserving hard links (cp -a keeps them within one invocation)."""
    import subprocess

    subprocess.run(["cp", "-a", str(src), str(dst)], check=True)


def test_every_version_records_every_data_file(pristine):
    for version in ("v1", "v2", "v3"):
        vdir = pristine / "versions" / version
        record = load_record(vdir)
        assert record is not None and record["algorithm"] == "sha256"
        assert record["record_version"] == 2
        assert sorted(record["files"]) == data_files(vdir)
        assert "manifest.json" not in record["files"]
        manifest = vdir / "manifest.json"
        assert record["manifest"] == {
            "bytes": manifest.stat().st_size,
            "sha256": sha256_file(manifest),
        }
        parent = json.loads(manifest.read_text())["parent"]
        if parent is None:
            assert record["parent"] is None
        else:
            assert record["parent"] == {
                "version": parent,
                "checksums_sha256": sha256_file(pristine / "versions" / parent / CHECKSUMS_FILE),
            }
        for rel, entry in record["files"].items():
            assert entry == {
                "bytes": (vdir / rel).stat().st_size,
                "sha256": sha256_file(vdir / rel),
            }
    assert any(
        rel.startswith("data.zarr/motion/rotmat/c/")
        for rel in load_record(pristine / "versions" / "v2")["files"]
    )
    assert "measures.parquet" in load_record(pristine / "versions" / "v3")["files"]
    assert validate_store(pristine, deep=True) == []


def test_files_are_shared_between_versions_by_hard_link(pristine):
    v1 = pristine / "versions" / "v1" / "data.zarr" / "motion" / "trans" / "c" / "0" / "0"
    v3 = pristine / "versions" / "v3" / "data.zarr" / "motion" / "trans" / "c" / "0" / "0"
    assert os.path.samefile(v1, v3)


def test_flipped_byte_in_a_shared_chunk_is_named_in_every_version_that_holds_it(store):
    rel = "data.zarr/motion/trans/c/0/0"
    _flip(store / "versions" / "v1" / rel)
    problems = validate_store(store, deep=True)
    assert len(problems) == 3, problems
    for version, others in (("v1", "v2, v3"), ("v2", "v1, v3"), ("v3", "v1, v2")):
        [line] = [p for p in problems if p.startswith(f"{version}: ")]
        assert f"array motion/trans chunk (0, 0) ({rel})" in line
        assert "sha256 differs" in line and f"the same file (hard link) is in {others}" in line


def test_flipped_byte_in_a_featurized_chunk_spares_the_versions_without_it(store):
    vdir = store / "versions" / "v2"
    rel = next(r for r in load_record(vdir)["files"] if r.startswith("data.zarr/motion/quat/c/"))
    _flip(vdir / rel)
    problems = validate_store(store, deep=True)
    assert [p.split(": ")[0] for p in problems] == ["v2", "v3"]  # v1 has no quat
    assert all("array motion/quat chunk" in p for p in problems)


@pytest.mark.slow
def test_corrupted_table_named_by_deep_validate_and_cli(store):
    _flip(store / "versions" / "v3" / "measures.parquet", offset=200)
    proc = run_cli("validate", str(store), "--deep", check=False)
    assert proc.returncode == 1
    assert "v3: table measures (measures.parquet): sha256 differs" in proc.stderr
    as_json = json.loads(run_cli("validate", str(store), "--deep", "--json", check=False).stdout)
    assert as_json["valid"] is False and as_json["deep"] is True
    assert any("table measures" in p for p in as_json["problems"])


def test_cheap_validate_catches_truncated_missing_and_stray_files(store):
    v2 = store / "versions" / "v2"
    chunk = next(p for p in (v2 / "data.zarr" / "motion" / "euler" / "c").rglob("*") if p.is_file())
    os.unlink(chunk)  # unlink: v2's link only, v3 keeps its own
    (v2 / "data.zarr" / "motion" / "euler" / "stray").write_bytes(b"x")
    seq = store / "versions" / "v1" / "sequences.parquet"
    os.truncate(seq, seq.stat().st_size - 10)  # shared by all three versions
    problems = validate_store(store)  # not deep
    text = "\n".join(problems)
    assert "v2: array motion/euler chunk" in text and ": missing" in text
    assert (
        "v2: zarr file motion/euler/stray (data.zarr/motion/euler/stray): file not recorded" in text
    )
    for version in ("v1", "v2", "v3"):
        assert f"{version}: table sequences (sequences.parquet): " in text
    size = seq.stat().st_size
    assert f"{size} bytes, {size + 10} recorded at commit; the same file (hard link)" in text


def test_corrupted_or_missing_record(store):
    v1, v2 = store / "versions" / "v1", store / "versions" / "v2"
    record = json.loads((v1 / CHECKSUMS_FILE).read_text())
    first = next(iter(record["files"]))
    record["files"][first]["sha256"] = "0" * 64
    (v1 / CHECKSUMS_FILE).write_text(json.dumps(record))
    (v2 / CHECKSUMS_FILE).unlink()
    cheap = validate_store(store)
    assert cheap == [
        "v1: checksums.json: its own digest does not match (the record is corrupted)",
        # v3 recorded v2's record at its commit: a record that vanished is not a legacy version
        "v3: checksums.json: parent v2's record is gone (recorded at commit)",
    ]
    deep = validate_store(store, deep=True)
    assert "v2: checksums.json: missing, so the data cannot be verified" in deep


def test_describe_file_names_chunks_arrays_and_tables():
    assert (
        describe_file("data.zarr/motion/rotmat/c/3/0/0/0")
        == "array motion/rotmat chunk (3, 0, 0, 0)"
    )
    assert describe_file("data.zarr/audio/stems/drums/mfcc/c/0/0") == (
        "array audio/stems/drums/mfcc chunk (0, 0)"
    )
    assert describe_file("data.zarr/motion/zarr.json") == "zarr metadata of motion"
    assert describe_file("data.zarr/zarr.json") == "zarr metadata of /"
    assert describe_file("splits.parquet") == "table splits"
    assert describe_file("notes.txt") == "file notes.txt"
