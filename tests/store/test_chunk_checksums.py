"""Readers never return wrong numbers silently (issue 11.5): a flipped byte, a deleted chunk or a
planted symbolic link raises a clear StoreError naming the array and chunk; a child version is
never committed on top of them; an edited manifest or a rewritten parent record is caught.

Real stores throughout (synthetic AIST++ ingested, featurized and segmented by dancedata); the
damage is done to the files on disk the way bit rot, a careless `rm` or an attacker would.
"""

from __future__ import annotations

import json
import os
import subprocess
from pathlib import Path

import numpy as np
import pytest
import zarr

import dancedata
from dancedata.errors import StoreError
from dancedata.featurize.featurize import FeaturizeOptions, featurize
from dancedata.featurize.segment import SegmentOptions, segment
from dancedata.ingest.aist import AistIngestOptions, ingest_aist
from dancedata.store import arrays as store_arrays
from dancedata.store.arrays import FrameArrayWriter, create_checked_array
from dancedata.store.build import BuildArea
from dancedata.store.chunks import ChunkGrid
from dancedata.store.integrity import (
    CHECKSUMS_FILE,
    _record_digest,
    array_grids,
    load_record,
    required_chunk_files,
)
from dancedata.store.layout import StoreLayout
from dancedata.store.validate import validate_store
from dancedata.synth.aist import synth_aist

TRANS = "data.zarr/motion/trans/c/0/0"
ZSTD_MAGIC = b"\x28\xb5\x2f\xfd"  # a zstd frame's first four bytes (0xFD2FB528, little-endian)


@pytest.fixture(scope="module")
def pristine(tmp_path_factory) -> Path:
    """v1 ingest, v2 motion-only featurize, v3 segment (no audio features: quick)."""
    root = tmp_path_factory.mktemp("chunks")
    synth_aist(root / "raw", n_sequences=3, seed=5)
    store = root / "store"
    ingest_aist(store, root / "raw", AistIngestOptions())
    featurize(store, FeaturizeOptions(audio=False))
    segment(store, SegmentOptions())
    return store


@pytest.fixture
def store(pristine, tmp_path) -> Path:
    """A private copy that keeps the hard links between versions (cp -a)."""
    copy = tmp_path / "store"
    subprocess.run(["cp", "-a", str(pristine), str(copy)], check=True)
    return copy


def _latest(store: Path) -> Path:
    layout = StoreLayout(store)
    return layout.version_dir(layout.latest())


def _rewrite(path: Path, data: bytes) -> None:
    """Replace a file's bytes in place (same inode: every hard link sees it, as with bit rot)."""
    with open(path, "r+b") as handle:
        handle.write(data)
        handle.truncate()


def _decode(payload: bytes) -> bytes:
    """A chunk's compressed payload (crc32c removed) decoded by its codec, zstd or blosc, as a
    reader that skips the checksum would."""
    from numcodecs import Blosc, Zstd

    codec = Zstd() if payload[:4] == ZSTD_MAGIC else Blosc()
    return bytes(codec.decode(payload))


def _silent_flip(chunk: Path) -> tuple[bytes, int]:
    """A copy of a crc32c chunk with one byte of its compressed payload flipped such that its
    codec alone still decodes it, to different numbers: the damage a reader without a checksum
    would pass on. Returns (damaged bytes, offset)."""
    raw = chunk.read_bytes()
    payload, good = raw[:-4], _decode(raw[:-4])
    for offset in range(len(payload) // 2, len(payload)):
        damaged = bytearray(payload)
        damaged[offset] ^= 0x01
        try:
            decoded = _decode(bytes(damaged))
        except Exception:
            continue
        if decoded != good:
            return bytes(damaged) + raw[-4:], offset
    raise AssertionError("no silently-decodable flip found")


def _delete_everywhere(store: Path, rel: str) -> None:
    """Delete a chunk from every version that holds it (all its hard links)."""
    for vdir in (store / "versions").iterdir():
        if (vdir / rel).exists():
            os.unlink(vdir / rel)


# -- the format ---------------------------------------------------------------------------------
def test_every_array_has_crc32c_and_every_chunk_of_its_grid(pristine):
    for version in ("v1", "v2", "v3"):
        vdir = pristine / "versions" / version
        grids = array_grids(vdir)
        assert "motion/trans" in grids and len(grids) >= 6
        for name, grid in grids.items():
            meta = json.loads((vdir / "data.zarr" / name / "zarr.json").read_text())
            assert meta["codecs"][-1] == {"name": "crc32c"}, name
            assert grid.crc32c
        record = load_record(vdir)["files"]
        for rel in required_chunk_files(vdir):
            assert (vdir / rel).is_file() and rel in record, rel


def test_all_zero_chunks_are_written_by_both_write_paths(tmp_path):
    """zarr skips chunks equal to the fill value by default; ours are all on disk, so that an
    absent chunk always means damage. Plain zarr reads them back (standard codecs only)."""
    group = zarr.open_group(tmp_path / "data.zarr", mode="w", zarr_format=3)
    writer = FrameArrayWriter(group, "streamed", (3,), np.float32, chunk_frames=4)
    writer.append(np.zeros((10, 3), np.float32))
    writer.close()
    create_checked_array(group, "regions", shape=(10, 2), chunks=(4, 2), dtype=np.float32)
    target = BuildArea(str(tmp_path)).open_array("regions")  # the featurize units' path
    target[0:10] = np.zeros((10, 2), np.float32)
    for name in ("streamed", "regions"):
        folder = tmp_path / "data.zarr" / name / "c"
        assert sorted(p.relative_to(folder).as_posix() for p in folder.rglob("*") if p.is_file())
        grid = ChunkGrid.from_metadata(
            json.loads((tmp_path / "data.zarr" / name / "zarr.json").read_text())
        )
        assert grid is not None and grid.grid_shape[0] == 3
        for key in grid.chunk_keys():
            assert (tmp_path / "data.zarr" / name / key).is_file(), (name, key)
        plain = zarr.open_array(tmp_path / "data.zarr" / name, mode="r")
        assert not np.asarray(plain[:]).any()


# -- a flipped byte -----------------------------------------------------------------------------
def test_flipped_byte_raises_naming_array_and_chunk(store):
    vdir = _latest(store)
    chunk = vdir / TRANS
    damaged, _ = _silent_flip(chunk)
    seq = dancedata.open_store(store).seq_ids()[0]
    good = np.asarray(zarr.open_array(vdir / "data.zarr" / "motion" / "trans", mode="r")[:])
    _rewrite(chunk, damaged)
    with pytest.raises(StoreError) as caught:
        dancedata.open_store(store).motion(seq, "trans")
    message = str(caught.value)
    assert f"{vdir / 'data.zarr'}: array motion/trans chunk c/0/0: crc32c" in message
    # a reader that skips the checksum gets wrong numbers without a word: the threat is real
    plain = zarr.open_array(vdir / "data.zarr" / "motion" / "trans", mode="r")
    unchecked = np.frombuffer(_decode(damaged[:-4]), np.float32).reshape(-1, 3)
    assert not np.array_equal(unchecked[: len(good)], good[: len(unchecked)])
    with pytest.raises(ValueError, match="checksum"):
        plain[:10]  # zarr itself refuses it too, without naming the chunk
    cheap = "\n".join(validate_store(store))  # not deep: the float scan reads every chunk
    assert "motion/trans" in cheap and "crc32c checksum mismatch" in cheap


# -- a deleted chunk ----------------------------------------------------------------------------
def test_deleted_chunk_is_an_error_to_read_and_never_inherited(store):
    rel = "data.zarr/motion/axis_angle/c/0/0/0"
    _delete_everywhere(store, rel)
    dance = dancedata.open_store(store)
    with pytest.raises(StoreError, match=r"array motion/axis_angle chunk c/0/0/0: missing"):
        dance.motion(dance.seq_ids()[0], "axis_angle")
    before = StoreLayout(store).committed_versions()
    with pytest.raises(StoreError) as caught:
        segment(store, SegmentOptions(beats_per_measure=3))  # carries axis_angle over
    assert "cannot commit" in str(caught.value)
    assert f"array motion/axis_angle chunk (0, 0, 0) ({rel}): missing (carried over from v3)" in (
        str(caught.value)
    )
    assert StoreLayout(store).committed_versions() == before  # nothing committed
    assert not StoreLayout(store).temp_dirs()  # nothing half-written left
    with pytest.raises(StoreError, match="motion/axis_angle chunk c/0/0/0: missing"):
        featurize(store, FeaturizeOptions(audio=False, representations=["quat"]))
    problems = validate_store(store)
    assert any(p.startswith("v3: array motion/axis_angle chunk (0, 0, 0)") for p in problems)


def test_record_built_from_files_present_is_caught(store):
    """A record written by the old code after a chunk went missing (files present only) does not
    list the chunk; the shape and chunk grid still call for it."""
    vdir = _latest(store)
    os.unlink(vdir / TRANS)  # this version's link only
    record = load_record(vdir)
    del record["files"][TRANS]
    record["digest"] = _record_digest(record)
    (vdir / CHECKSUMS_FILE).write_text(json.dumps(record))
    problems = validate_store(store, deep=True)
    assert f"v3: array motion/trans chunk (0, 0) ({TRANS}): required by the array's shape" in (
        "\n".join(problems)
    )


# -- a planted symbolic link --------------------------------------------------------------------
def test_planted_symlink_is_reported_and_never_inherited(store, tmp_path):
    vdir = _latest(store)
    planted = tmp_path / "planted"
    planted.write_bytes((vdir / TRANS).read_bytes())  # same bytes: only the link is wrong
    os.unlink(vdir / TRANS)
    os.symlink(planted, vdir / TRANS)
    problems = validate_store(store)
    assert f"v3: array motion/trans chunk (0, 0) ({TRANS}): is a symbolic link" in problems[0]
    with pytest.raises(StoreError, match="is a symbolic link in v3"):
        segment(store, SegmentOptions(beats_per_measure=3))
    assert StoreLayout(store).committed_versions() == ["v1", "v2", "v3"]


# -- manifests and the chain of records ---------------------------------------------------------
@pytest.mark.parametrize("field", ["fingerprint", "stages"])
def test_edited_manifest_is_caught(store, field):
    path = _latest(store) / "manifest.json"
    manifest = json.loads(path.read_text())
    if field == "fingerprint":
        manifest["fingerprint"] = "0" * 64
    else:
        manifest["stages"]["ingest"] = "f" * 64
    path.write_text(json.dumps(manifest, indent=2, sort_keys=True) + "\n")
    for deep in (False, True):
        assert validate_store(store, deep=deep) == [
            "v3: manifest.json: differs from the one recorded at commit in checksums.json "
            "(edited after commit: its fingerprint, stages or inputs cannot be trusted)"
        ]


def test_rewritten_parent_record_is_caught_by_the_child(store):
    """Editing v2's manifest and recomputing v2's record to match still leaves v3's record,
    which holds the hash of v2's record at v3's commit."""
    v2 = store / "versions" / "v2"
    path = v2 / "manifest.json"
    manifest = json.loads(path.read_text())
    manifest["stages"]["featurize"] = "f" * 64
    path.write_text(json.dumps(manifest))
    record = load_record(v2)
    record["manifest"] = {"bytes": path.stat().st_size, "sha256": _sha(path)}
    record["digest"] = _record_digest(record)
    (v2 / CHECKSUMS_FILE).write_text(json.dumps(record))
    assert validate_store(store) == [
        "v3: checksums.json: parent v2's checksums.json differs from the one recorded when this "
        "version was committed (the parent's record was rewritten)"
    ]


def _sha(path: Path) -> str:
    import hashlib

    return hashlib.sha256(path.read_bytes()).hexdigest()


# -- stores written before the crc32c codec -----------------------------------------------------
@pytest.fixture
def legacy_store(tmp_path, monkeypatch) -> Path:
    """A store written the way dancedata wrote them before crc32c: zstd only, zero chunks
    skipped. Reading it must still work; checksums.json stands in for the codec."""
    from zarr.codecs import ZstdCodec

    def old_compressors(compressors="auto"):
        return [ZstdCodec(level=0, checksum=False)] if compressors == "auto" else compressors

    monkeypatch.setattr(store_arrays, "checked_compressors", old_compressors)
    monkeypatch.setitem(store_arrays.WRITE_CONFIG, "write_empty_chunks", False)
    synth_aist(tmp_path / "raw", n_sequences=2, seed=9)
    ingest_aist(tmp_path / "store", tmp_path / "raw", AistIngestOptions())
    monkeypatch.undo()
    return tmp_path / "store"


def test_legacy_store_reads_and_is_checked_against_checksums_json(legacy_store):
    vdir = legacy_store / "versions" / "v1"
    assert not array_grids(vdir)["motion/trans"].crc32c
    dance = dancedata.open_store(legacy_store)
    seq = dance.seq_ids()[0]
    good = dance.motion(seq, "trans").copy()
    assert good.shape[1] == 3 and np.isfinite(good).all()
    assert validate_store(legacy_store, deep=True) == []
    raw = bytearray((vdir / TRANS).read_bytes())
    raw[len(raw) // 2] ^= 0xFF
    _rewrite(vdir / TRANS, bytes(raw))
    with pytest.raises(StoreError, match="array motion/trans chunk c/0/0: sha256 differs from"):
        dancedata.open_store(legacy_store).motion(seq, "trans")
    os.unlink(vdir / TRANS)
    with pytest.raises(StoreError, match="chunk c/0/0: missing, but checksums.json recorded it"):
        dancedata.open_store(legacy_store).motion(seq, "trans")
    with pytest.raises(StoreError, match=r"motion/trans chunk \(0, 0\).*missing \(carried over"):
        segment(legacy_store, SegmentOptions())


def test_info_shows_the_hash_of_the_newest_record(pristine):
    from dancedata.store.summary import format_info, summarize

    info = summarize(pristine)
    assert info["checksums_sha256"] == _sha(pristine / "versions" / "v3" / CHECKSUMS_FILE)
    assert f"record    checksums.json sha256 {info['checksums_sha256']}" in format_info(info)


def test_arrays_opened_by_a_reader_pickle_with_their_checks(store):
    """Dask and worker processes may ship an open array: the copy still refuses bad chunks."""
    import pickle

    from dancedata.store.reader import _VersionReader

    array = _VersionReader(store).array("motion/trans")
    copy = pickle.loads(pickle.dumps(array))
    assert np.array_equal(np.asarray(copy[:]), np.asarray(array[:]))
    _delete_everywhere(store, TRANS)
    with pytest.raises(StoreError, match="array motion/trans chunk c/0/0: missing"):
        pickle.loads(pickle.dumps(array))[:5]
