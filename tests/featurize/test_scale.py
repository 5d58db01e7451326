"""Issue 7/8: parallel featurize (process pool, Dask LocalCluster) writes the same bytes as a
serial run, and interrupted featurize / ingest runs resume from the units they finished."""

from __future__ import annotations

import hashlib
import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest

import dancedata
import dancedata.featurize.featurize as featurize_module
import dancedata.ingest.aist.source as aist_module
from dancedata.featurize.featurize import FeaturizeOptions, featurize
from dancedata.featurize.segment import SegmentOptions, segment
from dancedata.featurize.tasks import plan_motion_tasks as plan_motion_units
from dancedata.ingest import resumable_reads as reads_module
from dancedata.ingest.aist import AistIngestOptions, ingest_aist
from dancedata.store.arrays import CHUNK_FRAMES
from dancedata.store.layout import StoreLayout
from dancedata.store.validate import validate_store
from dancedata.synth.aist import synth_aist
from tests.helpers import REPO, run_cli

# slow: process pools and a Dask LocalCluster featurize the same 12-sequence store
pytestmark = pytest.mark.slow

SMALL_UNITS = 4096  # 12 sequences (~11,900 frames) → two chunk-aligned motion units


def version_files(store: Path, version: str) -> dict[str, str]:
    """sha256 of every file of a version but its manifest (which records times and counts);
    of checksums.json, only its ``files`` (the rest hashes the manifests)."""
    root = store / "versions" / version

    def digest(path: Path) -> str:
        data = path.read_bytes()
        if path == root / "checksums.json":
            data = json.dumps(json.loads(data)["files"], sort_keys=True).encode()
        return hashlib.sha256(data).hexdigest()

    return {
        p.relative_to(root).as_posix(): digest(p)
        for p in sorted(root.rglob("*"))
        if p.is_file() and p.name != "manifest.json"
    }


def fresh_store(raw: Path, store: Path) -> Path:
    ingest_aist(store, raw, AistIngestOptions())
    return store


@pytest.fixture(autouse=True)
def cold_feature_cache(tmp_path, monkeypatch):
    """Every run computes its audio: the per-track feature cache (dancedata.featurize.feature_cache)
    starts empty in each test, so engines are compared on what they compute."""
    monkeypatch.setenv("DANCEDATA_CACHE", str(tmp_path / "feature-cache"))


@pytest.fixture(scope="module")
def data(tmp_path_factory):
    root = tmp_path_factory.mktemp("scale")
    raw = root / "raw"
    synth_aist(raw, n_sequences=12, seed=11)
    serial = fresh_store(raw, root / "serial")
    with pytest.MonkeyPatch.context() as patch:
        patch.setenv("DANCEDATA_CACHE", str(root / "feature-cache"))
        result = featurize(serial, FeaturizeOptions(task_frames=SMALL_UNITS))
    return {"root": root, "raw": raw, "serial": serial, "result": result}


def test_serial_run_records_its_units(data):
    counts = data["result"].counts
    assert counts["units"] == 2 + 6  # two motion units, six tracks
    assert counts["resumed_units"] == 0
    assert counts["engine"] == {"engine": "serial", "workers": 1}
    assert validate_store(data["serial"]) == []
    assert StoreLayout(data["serial"]).temp_dirs() == []


def test_two_worker_processes_write_the_same_bytes(data):
    store = fresh_store(data["raw"], data["root"] / "workers")
    out = run_cli("featurize", str(store), "--workers", "2", "-q", "--json").stdout
    counts = json.loads(out)["counts"]
    assert counts["engine"] == {"engine": "processes", "workers": 2}
    # Planned differently (one motion unit here, two there): the bytes do not depend on it.
    assert counts["units"] == 1 + 6
    assert version_files(store, "v2") == version_files(data["serial"], "v2")


def test_dask_local_cluster_writes_the_same_bytes(data):
    pytest.importorskip("distributed")
    store = fresh_store(data["raw"], data["root"] / "dask")
    result = featurize(store, FeaturizeOptions(task_frames=SMALL_UNITS, dask="local:2"))
    assert result.counts["engine"]["engine"] == "dask"
    assert result.counts["engine"]["workers"] == 2
    assert version_files(store, "v2") == version_files(data["serial"], "v2")


def test_a_failed_unit_is_retried_on_dask(data, tmp_path):
    pytest.importorskip("distributed")
    from dancedata.exec.executors import DaskExecutor

    flag = tmp_path / "failed-once"
    with DaskExecutor("local:1") as executor:
        results = dict(executor.map_unordered(_flaky_square, [(2, str(flag)), (3, str(flag))]))
    assert results == {0: 4, 1: 9}
    assert flag.exists()


def _flaky_square(item: tuple[int, str]) -> int:
    """Fails the first time it is ever called (per flag file), then squares."""
    value, flag = item
    if not os.path.exists(flag):
        Path(flag).touch()
        raise RuntimeError("transient failure")
    return value * value


def test_motion_units_are_chunk_aligned_and_cover_every_frame_once():
    rng = np.random.default_rng(0)
    lengths = rng.integers(1, 3000, size=400)
    lengths[37] = 50_000  # one sequence much longer than a chunk
    stops = np.cumsum(lengths)
    starts = stops - lengths
    for target in (1, 4096, CHUNK_FRAMES, 3 * CHUNK_FRAMES):
        units = plan_motion_units(starts, stops, CHUNK_FRAMES, target)
        assert units[0].frame_start == 0 and units[-1].frame_stop == stops[-1]
        reads_of = np.zeros(len(lengths), dtype=int)
        for a, b in zip(units, units[1:], strict=False):
            assert a.frame_stop == b.frame_start
        for unit in units:
            assert unit.frame_start % CHUNK_FRAMES == 0
            assert unit.frame_stop % CHUNK_FRAMES == 0 or unit.frame_stop == stops[-1]
            # whole sequences are read, and they cover the unit's rows
            assert unit.read_start <= unit.frame_start and unit.frame_stop <= unit.read_stop
            inside = (starts >= unit.read_start) & (stops <= unit.read_stop)
            assert starts[inside].min() == unit.read_start
            assert stops[inside].max() == unit.read_stop
            assert len(unit.bounds) == inside.sum()
            reads_of[inside] += 1
        assert reads_of.max() <= 2  # a sequence is computed by at most two units
        assert reads_of[37] == 1 or target < CHUNK_FRAMES


# -- resume ------------------------------------------------------------------------------------
def test_featurize_interrupted_by_an_error_resumes_and_matches(data, monkeypatch):
    store = fresh_store(data["raw"], data["root"] / "interrupted")
    calls = {"n": 0}
    real = featurize_module.run_audio_task

    def crash_on_third_track(job, unit):
        calls["n"] += 1
        if calls["n"] == 3:
            raise RuntimeError("worker crashed")
        return real(job, unit)

    monkeypatch.setattr(featurize_module, "run_audio_task", crash_on_third_track)
    with pytest.raises(RuntimeError, match="worker crashed"):
        featurize(store, FeaturizeOptions(task_frames=SMALL_UNITS))
    layout = StoreLayout(store)
    assert layout.committed_versions() == ["v1"]
    [temp] = layout.temp_dirs()  # kept for the next run, named from the fingerprint
    assert temp.name.startswith(".tmp-") and len(temp.name) == len(".tmp-") + 16
    monkeypatch.setattr(featurize_module, "run_audio_task", real)

    result = featurize(store, FeaturizeOptions(task_frames=SMALL_UNITS))
    assert result.counts["resumed_units"] == 2  # tracks run first: two had finished
    assert result.counts["units"] == 8
    assert layout.temp_dirs() == []
    assert version_files(store, "v2") == version_files(data["serial"], "v2")


def test_featurize_killed_by_sigkill_resumes_and_matches(data):
    store = fresh_store(data["raw"], data["root"] / "killed")
    v1 = version_files(store, "v1")
    proc = subprocess.Popen(
        [sys.executable, "-m", "dancedata.cli", "featurize", str(store), "-q"],
        cwd=REPO,
        stdout=subprocess.DEVNULL,
        stderr=subprocess.DEVNULL,
        start_new_session=True,
    )
    markers = store / "versions"
    deadline = time.monotonic() + 120
    while time.monotonic() < deadline and proc.poll() is None:
        if len(list(markers.glob(".tmp-*/.build/units/audio/*.json"))) >= 2:
            break
        time.sleep(0.02)
    assert proc.poll() is None, "featurize finished before it could be killed"
    os.killpg(proc.pid, signal.SIGKILL)
    proc.wait()

    layout = StoreLayout(store)
    assert layout.committed_versions() == ["v1"] and version_files(store, "v1") == v1
    assert validate_store(store) == []
    summary = json.loads(run_cli("featurize", str(store), "-q", "--json").stdout)
    assert summary["version"] == "v2"
    assert summary["counts"]["resumed_units"] >= 2
    assert layout.temp_dirs() == []
    assert version_files(store, "v2") == version_files(data["serial"], "v2")


def test_ingest_interrupted_resumes_its_read_batches(data, tmp_path, monkeypatch):
    monkeypatch.setattr(reads_module, "DEFAULT_BATCH", 4)
    reference = tmp_path / "reference"
    done = ingest_aist(reference, data["raw"], AistIngestOptions())
    assert done.counts["units"] == 3 and done.counts["resumed_units"] == 0

    store = tmp_path / "store"
    calls = {"n": 0}
    real = aist_module._read_sequence

    def crash_on_sixth(files):
        calls["n"] += 1
        if calls["n"] == 6:
            raise KeyboardInterrupt
        return real(files)

    monkeypatch.setattr(aist_module, "_read_sequence", crash_on_sixth)
    with pytest.raises(KeyboardInterrupt):
        ingest_aist(store, data["raw"], AistIngestOptions())
    assert StoreLayout(store).committed_versions() == []
    monkeypatch.setattr(aist_module, "_read_sequence", real)
    resumed = ingest_aist(store, data["raw"], AistIngestOptions())
    assert resumed.counts["resumed_units"] == 1 and resumed.counts["units"] == 3
    assert version_files(store, "v1") == version_files(reference, "v1")


def test_measure_windows_match_iter_measures(data):
    segment(data["serial"], SegmentOptions())
    store = dancedata.open_store(data["serial"])
    windows = store.measure_windows()
    expected = {(m.seq_id, m.measure): m for m in store.iter_measures()}
    assert len(windows) == len(expected) > 0
    for i in range(len(windows)):
        m = expected[(windows.seq_ids[i], int(windows.measure[i]))]
        motion, audio = windows[i]
        assert motion.dtype == audio.dtype == np.float32
        assert np.array_equal(motion, m.motion) and np.array_equal(audio, m.audio)
    assert sum(1 for _ in windows.sample(50, seed=1)) == 50
