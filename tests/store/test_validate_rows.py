"""``validate`` checks every row of every float array for NaN/Inf, chunk by chunk (issue 11.2),
and reports a damaged manifest as one line naming the file instead of crashing (issue 11.6)."""

from __future__ import annotations

import json
import subprocess
from pathlib import Path

import numpy as np
import pytest
import zarr

from dancedata.ingest.aist import AistIngestOptions, ingest_aist
from dancedata.store.arrays import FrameArrayWriter
from dancedata.store.reader import _VersionReader
from dancedata.store.validate import nonfinite_rows, validate_store
from dancedata.store.writer import VersionWriter
from dancedata.synth.aist import synth_aist
from tests.helpers import run_cli


# -- the scan against a brute-force reference ---------------------------------------------------
def _reference(values: np.ndarray, allow_nan: bool) -> tuple[int, int]:
    flat = values.reshape(values.shape[0], -1)
    bad = np.isinf(flat) if allow_nan else ~np.isfinite(flat)
    rows = np.flatnonzero(bad.any(axis=1))
    return int(rows.size), int(rows[0]) if rows.size else -1


@pytest.mark.parametrize("row_shape", [(), (3,), (4, 3, 3)])
@pytest.mark.parametrize("seed", range(6))
def test_scan_matches_brute_force(tmp_path, row_shape, seed):
    rng = np.random.default_rng(seed)
    n = int(rng.integers(1, 200))
    values = rng.normal(scale=1e30, size=(n, *row_shape)).astype(np.float32)  # near overflow
    for _ in range(int(rng.integers(0, 5))):
        row = int(rng.integers(0, n))
        flat = values[row].reshape(-1)
        flat[int(rng.integers(0, flat.size))] = rng.choice([np.nan, np.inf, -np.inf])
    group = zarr.open_group(tmp_path / "a.zarr", mode="w", zarr_format=3)
    writer = FrameArrayWriter(group, "x", row_shape, np.float32, chunk_frames=7)
    writer.append(values)
    writer.close()
    array = zarr.open_array(tmp_path / "a.zarr" / "x", mode="r")
    for allow_nan in (False, True):
        assert nonfinite_rows(array, allow_nan=allow_nan) == _reference(values, allow_nan)


def test_scan_reads_a_few_chunks_at_a_time(tmp_path):
    group = zarr.open_group(tmp_path / "a.zarr", mode="w", zarr_format=3)
    writer = FrameArrayWriter(group, "x", (2,), np.float32, chunk_frames=10)
    writer.append(np.ones((95, 2), np.float32))
    writer.close()
    array = zarr.open_array(tmp_path / "a.zarr" / "x", mode="r")

    class Recording:
        """The real array, with the row ranges read noted."""

        shape, ndim, chunks = array.shape, array.ndim, array.chunks
        reads: list[tuple[int, int]] = []

        def __getitem__(self, key: slice) -> np.ndarray:
            self.reads.append((key.start, key.stop))
            return array[key]

    recording = Recording()
    assert nonfinite_rows(recording, allow_nan=False, chunks=2) == (0, -1)
    assert recording.reads == [(0, 20), (20, 40), (40, 60), (60, 80), (80, 100)]


# -- stores -------------------------------------------------------------------------------------
@pytest.fixture(scope="module")
def ingested(tmp_path_factory) -> Path:
    root = tmp_path_factory.mktemp("rows")
    synth_aist(root / "raw", n_sequences=2, seed=3)
    ingest_aist(root / "store", root / "raw", AistIngestOptions())
    return root / "store"


@pytest.fixture
def store(ingested, tmp_path) -> Path:
    copy = tmp_path / "store"
    subprocess.run(["cp", "-a", str(ingested), str(copy)], check=True)
    return copy


def _commit_with(store: Path, name: str, values: np.ndarray, attrs: dict | None = None) -> str:
    """Commit a child of the latest version holding one more float array (real writer)."""
    parent = _VersionReader(store)
    with VersionWriter(
        store,
        command="test",
        config={"array": name},
        fingerprint=name.replace("/", "-") + str(values.shape),
        parent=parent.version,
        parent_stages=parent.manifest.get("stages"),
    ) as version:
        group_name, array_name = name.rsplit("/", 1)
        group = version.zarr_group().require_group(group_name)
        writer = FrameArrayWriter(group, array_name, values.shape[1:], values.dtype, attrs=attrs)
        writer.append(values)
        writer.close()
        return version.commit()


@pytest.mark.slow
def test_nan_in_the_last_row_of_positions_is_found(store):
    """Positions were left out, and only 4096 rows were sampled: the last row of a long array
    went unchecked."""
    reader = _VersionReader(store)
    frames = reader.array("motion/trans").shape[0]
    joints = reader.array("motion/axis_angle").shape[1]
    assert frames > 1
    positions = np.zeros((frames, joints, 3), np.float32)
    positions[-1, 5, 2] = np.nan
    name = _commit_with(store, "motion/positions", positions)
    assert validate_store(store, name) == [
        f"{name}: motion/positions: 1 rows hold NaN or Inf (first: row {frames - 1})"
    ]


def test_every_row_of_a_long_array_is_checked(store):
    values = np.linspace(0, 1, 20000 * 2, dtype=np.float32).reshape(20000, 2)
    values[19_999, 0] = np.inf
    values[17_000, 1] = -np.inf
    name = _commit_with(store, "motion/extra_feature", values)
    assert validate_store(store, name) == [
        f"{name}: motion/extra_feature: 2 rows hold NaN or Inf (first: row 17000)"
    ]


def test_nan_is_allowed_only_where_the_attrs_declare_it(store):
    values = np.ones((9000, 3), np.float32)
    values[8500] = np.nan
    name = _commit_with(store, "motion/marker_like", values, attrs={"missing": "NaN"})
    assert validate_store(store, name) == []
    values[8800, 1] = np.inf
    name = _commit_with(store, "motion/marker_like2", values, attrs={"missing": "NaN"})
    assert validate_store(store, name) == [
        f"{name}: motion/marker_like2: 1 rows hold Inf (first: row 8800)"
    ]


# -- damaged manifests --------------------------------------------------------------------------
def _damage(manifest: dict, how: str) -> object:
    if how == "list":
        return [1, 2]
    changed = dict(manifest)
    key, value = how.split("=", 1)
    changed[key] = json.loads(value)
    return changed


@pytest.mark.slow
@pytest.mark.parametrize(
    "how",
    [
        "list",
        "skipped=[1]",
        'inputs="x"',
        "inputs=[3]",
        "stages=3",
        'stages={"ingest": 4}',
        "fingerprint=5",
        "config=[]",
        "counts=null",
    ],
)
def test_damaged_manifest_is_one_line_naming_the_file(store, how):
    path = store / "versions" / "v1" / "manifest.json"
    path.write_text(json.dumps(_damage(json.loads(path.read_text()), how)))
    proc = run_cli("validate", str(store), check=False)
    assert proc.returncode == 1, proc.stdout + proc.stderr
    assert "Traceback" not in proc.stderr
    assert f"{path}: " in proc.stdout + proc.stderr
    as_json = json.loads(run_cli("validate", str(store), "--json", check=False).stdout)
    assert as_json["valid"] is False
    assert any(str(path) in p for p in as_json["problems"])


def test_version_folder_without_manifest_is_reported(store):
    path = store / "versions" / "v1" / "manifest.json"
    path.unlink()
    problems = validate_store(store)
    assert f"{path}: missing (a damaged or half-restored version)" in problems


def test_scan_reads_stay_within_the_byte_budget(tmp_path):
    """A keypoints2d-sized chunk (8192 × 9 × 17 × 3 float32, 15 MB) is read two at a time."""
    from dancedata.store.validate import _SCAN_BYTES, scan_chunks

    group = zarr.open_group(tmp_path / "a.zarr", mode="w", zarr_format=3)
    wide = FrameArrayWriter(group, "wide", (9, 17, 3), np.float32).array
    narrow = FrameArrayWriter(group, "narrow", (3,), np.float32).array
    assert scan_chunks(wide) == 2 and _SCAN_BYTES >= 2 * 8192 * 9 * 17 * 3 * 4
    assert scan_chunks(narrow) == 4
