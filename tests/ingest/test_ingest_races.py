"""No lost update in the ingest commands (issue 11, item 3): an ingest that waited for the store
lock chooses its parent, checks whether its result is already there and (for ``ingest bvh
--append``) reads the version it appends to only once it holds the lock.

Each race is made deterministic without mocking anything. Either the test itself holds the
store's writer lock (a real :class:`StoreLock`, as any writer takes it) while real ``dancedata
ingest ... --wait`` subprocesses plan and queue behind it, or, as in tests/store/test_races.py, a
real ingest is frozen with SIGSTOP as soon as it holds the lock. The test waits until each queued
command reports "waiting for the store lock" before letting the lock go.
"""

from __future__ import annotations

import json
import subprocess
from collections.abc import Callable, Iterator
from pathlib import Path

import numpy as np
import pytest

from dancedata.ingest.aist import AistIngestOptions, ingest_aist
from dancedata.io.bvh import BvhClip, BvhSkeleton, write_bvh
from dancedata.store.layout import StoreLayout
from dancedata.store.lock import LOCK_FILE, StoreLock
from dancedata.store.reader import _VersionReader
from dancedata.store.validate import validate_store
from dancedata.synth.aist import synth_aist
from tests import race_harness as race
from tests.helpers import run_cli

# slow: concurrent ingest subprocesses race on one store
pytestmark = pytest.mark.slow

# ----------------------------------------------------------------------------- processes


def _queued(store: Path, tmp_path: Path, commands: list[tuple[str, ...]]) -> list[str]:
    """Run ``commands`` (each with ``--wait``) while this test holds the store lock: every one
    plans and queues behind it; then release it. Returns their stdouts, in start order."""
    lock = StoreLock(store, command="test_ingest_races")
    lock.acquire()
    procs, errs = [], []
    try:
        for i, args in enumerate(commands):
            err = tmp_path / f"queued-{i}.err"
            proc = race.start(*args, "--wait", stderr=err)
            procs.append(proc)
            errs.append(err)
            race.waiting(proc, err)
    except BaseException:
        for proc in procs:
            proc.kill()
        raise
    finally:
        lock.release()
    outs = [proc.communicate(timeout=race.TIMEOUT_S)[0] for proc in procs]
    codes = [proc.returncode for proc in procs]
    assert codes == [0] * len(procs), (codes, outs, [e.read_text() for e in errs])
    return outs


@pytest.fixture
def frozen() -> Iterator[Callable[..., subprocess.Popen]]:
    """Start a real command and freeze it (SIGSTOP) as soon as it holds the store lock."""
    started: list[subprocess.Popen] = []

    def freeze(store: Path, *args: str, stderr: Path) -> subprocess.Popen:
        proc = race.freeze(store, *args, stderr=stderr, what="the first command to take the lock")
        started.append(proc)
        return proc

    yield freeze
    for proc in started:
        race.finish(proc)


def _behind_frozen(frozen_proc: subprocess.Popen, tmp_path: Path, *args: str) -> tuple[str, str]:
    """Start ``dancedata ARGS --wait`` while ``frozen_proc`` holds the lock, let it finish,
    then return (stdout of the frozen command, stdout of the queued one)."""
    out_first, out, _ = race.queue_behind(frozen_proc, tmp_path, *args)
    return out_first, out


def _settled(store: Path) -> None:
    """Nothing left behind: no temporary version, no lock, a valid store."""
    layout = StoreLayout(store)
    assert layout.temp_dirs() == []
    assert not (store / LOCK_FILE).exists()
    assert validate_store(store) == []


# ----------------------------------------------------------------------------- AIST++


@pytest.fixture(scope="module")
def raw_aist(tmp_path_factory) -> tuple[Path, Path]:
    """Two small synthetic AIST++ roots with different data."""
    base = tmp_path_factory.mktemp("ingest-races")
    first, second = base / "raw-a", base / "raw-b"
    synth_aist(first, n_sequences=2, seed=3)
    synth_aist(second, n_sequences=2, seed=4)
    return first, second


def _ingest_aist(raw: Path, store: Path) -> tuple[str, ...]:
    return ("ingest", "aist", str(raw), "--store", str(store), "-q")


def test_queued_aist_ingests_of_the_same_data_commit_one_version(raw_aist, tmp_path):
    raw, _ = raw_aist
    store = tmp_path / "store"
    StoreLayout(store).ensure()  # an empty store, so that the test can hold its lock
    outs = _queued(store, tmp_path, [_ingest_aist(raw, store)] * 2)
    assert StoreLayout(store).committed_versions() == ["v1"], outs
    assert sorted(outs) == [
        "ingest aist: nothing to do, version v1 already holds this result\n",
        "ingest aist: wrote version v1\n",
    ]
    _settled(store)


def test_a_new_store_being_created_by_another_writer_is_not_refused(raw_aist, tmp_path):
    """Two ingests started together into a new store: the second looks while the first has
    made versions/ (and store.json's temporary file) but not store.json yet. It used to stop
    with "directory exists, is not empty and is not a dancedata store" (23 of 30 runs of two
    synchronised processes); it now joins in. A folder holding anything else is still refused."""
    from dancedata.errors import StoreError

    store = tmp_path / "store"
    (store / "versions").mkdir(parents=True)
    (store / ".tmp-store.json.12345").write_text("{")
    run_cli(*_ingest_aist(raw_aist[0], store))
    assert StoreLayout(store).committed_versions() == ["v1"]
    other = tmp_path / "not-a-store"
    other.mkdir()
    (other / "notes.txt").write_text("mine")
    with pytest.raises(StoreError, match="is not empty and is not a dancedata store"):
        StoreLayout(other).ensure()
    (other / "notes.txt").unlink()
    (other / "versions" / "v1").mkdir(parents=True)  # not the empty folder a creator makes
    with pytest.raises(StoreError, match="is not empty and is not a dancedata store"):
        StoreLayout(other).ensure()


def test_aist_ingest_queued_behind_the_same_ingest_writes_nothing(raw_aist, frozen, tmp_path):
    raw, other = raw_aist
    store = tmp_path / "store"
    run_cli(*_ingest_aist(other, store))  # v1: other data
    first = frozen(store, *_ingest_aist(raw, store), stderr=tmp_path / "first.err")
    out_first, out = _behind_frozen(first, tmp_path, *_ingest_aist(raw, store))
    assert out_first == "ingest aist: wrote version v2\n"
    assert out == "ingest aist: nothing to do, version v2 already holds this result\n"
    assert StoreLayout(store).committed_versions() == ["v1", "v2"]
    _settled(store)


def test_queued_aist_ingests_of_different_data_record_their_real_parent(raw_aist, tmp_path):
    """A replacing ingest carries nothing over, but its manifest names the version it
    replaced: the one that was latest when it wrote, not when it started."""
    raw, other = raw_aist
    store = tmp_path / "store"
    StoreLayout(store).ensure()
    _queued(store, tmp_path, [_ingest_aist(raw, store), _ingest_aist(other, store)])
    layout = StoreLayout(store)
    assert layout.committed_versions() == ["v1", "v2"]
    assert [layout.read_manifest(v)["parent"] for v in ("v1", "v2")] == [None, "v1"]
    _settled(store)


def test_nothing_to_do_names_the_latest_version_when_it_is_another(raw_aist, tmp_path):
    raw, other = raw_aist
    store = tmp_path / "store"
    run_cli(*_ingest_aist(raw, store))
    run_cli(*_ingest_aist(other, store))
    again = run_cli(*_ingest_aist(raw, store)).stdout
    # (the CLI goes on with how to make v1 the latest: see tests/store/test_checkout.py)
    assert again.startswith(
        "ingest aist: nothing to do, version v1 already holds this result; the latest version is v2"
    )
    assert again.count("the latest version is") == 1
    result = ingest_aist(store, raw, AistIngestOptions())
    assert (result.created, result.version, result.latest) == (False, "v1", "v2")


# ----------------------------------------------------------------------------- BVH


def _bvh(path: Path, turn_deg: float, n_frames: int = 240) -> Path:
    """A three-joint chain (the same rig in every file, 50 cm bones, 30 frames/s) turning by
    ``turn_deg`` per frame about Z: files differ in their motion only."""
    channels = [("Xposition", "Yposition", "Zposition", "Zrotation", "Xrotation", "Yrotation")]
    channels += [("Zrotation", "Xrotation", "Yrotation")] * 2
    skeleton = BvhSkeleton(
        ("hips", "spine", "head"),
        (-1, 0, 1),
        np.array([[0.0, 90.0, 0.0], [0.0, 50.0, 0.0], [0.0, 50.0, 0.0]]),
        tuple(channels),
        end_sites=(np.zeros((0, 3)), np.zeros((0, 3)), np.array([[0.0, 20.0, 0.0]])),
    )
    angle = (turn_deg * np.arange(n_frames)) % 360.0 - 180.0
    euler = np.stack([angle, np.zeros(n_frames), np.zeros(n_frames)], axis=1)
    values = np.concatenate([np.tile([0.0, 90.0, 0.0], (n_frames, 1))] + [euler] * 3, axis=1)
    write_bvh(BvhClip(skeleton, 1.0 / 30.0, values), path)
    return path


@pytest.fixture
def bvh_store(tmp_path: Path) -> tuple[Path, dict[str, Path]]:
    """A store whose v1 holds ``base.bvh``, and two more files to append, ``a`` and ``b``."""
    files = {
        name: _bvh(tmp_path / f"{name}.bvh", turn)
        for name, turn in (("base", 1.0), ("a", 2.0), ("b", 3.0))
    }
    store = tmp_path / "store"
    run_cli(*_ingest_bvh(store, files["base"]))
    return store, files


def _ingest_bvh(store: Path, *paths: Path, append: bool = False) -> tuple[str, ...]:
    flags = ("--append",) if append else ()
    return ("ingest", "bvh", *map(str, paths), "--store", str(store), *flags, "-q")


def _seq_ids(store: Path, version: str | None = None) -> list[str]:
    return _VersionReader(store, version).table("sequences").column("seq_id").to_pylist()


def _euler(store: Path, seq_id: str, version: str | None = None) -> np.ndarray:
    reader = _VersionReader(store, version)
    rows = {r["seq_id"]: r for r in reader.table("sequences").to_pylist()}
    row = rows[seq_id]
    return np.asarray(reader.array("motion/euler")[row["frame_start"] : row["frame_stop"]])


def test_queued_bvh_appends_both_land(bvh_store, tmp_path):
    """Two appends planned while another writer held the lock: the second one to write appends
    to the first one's result, so the latest version holds both files (no lost update)."""
    store, files = bvh_store
    outs = _queued(
        store,
        tmp_path,
        [_ingest_bvh(store, files["a"], append=True), _ingest_bvh(store, files["b"], append=True)],
    )
    assert sorted(outs) == ["ingest bvh: wrote version v2\n", "ingest bvh: wrote version v3\n"]
    layout = StoreLayout(store)
    assert layout.committed_versions() == ["v1", "v2", "v3"]
    assert [layout.read_manifest(v)["parent"] for v in ("v2", "v3")] == ["v1", "v2"]
    seq_ids = _seq_ids(store)
    assert seq_ids[0] == "base" and sorted(seq_ids[1:]) == ["a", "b"]
    assert _seq_ids(store, "v2") == seq_ids[:2]
    # every sequence's frames are the ones its own file gave (v1 for base, v2 for the first)
    np.testing.assert_array_equal(_euler(store, "base"), _euler(store, "base", "v1"))
    np.testing.assert_array_equal(_euler(store, seq_ids[1]), _euler(store, seq_ids[1], "v2"))
    assert not np.array_equal(_euler(store, "a"), _euler(store, "b"))
    _settled(store)


def test_bvh_append_queued_behind_a_frozen_append_appends_to_its_result(
    bvh_store, frozen, tmp_path
):
    store, files = bvh_store
    first = frozen(
        store, *_ingest_bvh(store, files["a"], append=True), stderr=tmp_path / "first.err"
    )
    out_first, out = _behind_frozen(first, tmp_path, *_ingest_bvh(store, files["b"], append=True))
    assert (out_first, out) == ("ingest bvh: wrote version v2\n", "ingest bvh: wrote version v3\n")
    assert _seq_ids(store) == ["base", "a", "b"]
    assert _VersionReader(store).manifest["parent"] == "v2"
    assert _VersionReader(store).manifest["counts"]["appended_to"] == "v2"
    _settled(store)


def test_queued_identical_bvh_appends_commit_one_version(bvh_store, tmp_path):
    store, files = bvh_store
    outs = _queued(store, tmp_path, [_ingest_bvh(store, files["a"], append=True)] * 2)
    assert sorted(outs) == [
        "ingest bvh: nothing to do, version v2 already holds this result\n",
        "ingest bvh: wrote version v2\n",
    ]
    assert StoreLayout(store).committed_versions() == ["v1", "v2"]
    assert _seq_ids(store) == ["base", "a"]
    _settled(store)


def test_queued_bvh_replacements_record_their_real_parent(bvh_store, tmp_path):
    store, files = bvh_store
    _queued(store, tmp_path, [_ingest_bvh(store, files["a"]), _ingest_bvh(store, files["b"])])
    layout = StoreLayout(store)
    assert [layout.read_manifest(v)["parent"] for v in ("v2", "v3")] == ["v1", "v2"]
    assert len(_seq_ids(store)) == 1
    _settled(store)


# ----------------------------------------------------------------------------- video


def _video(folder: Path, n_frames: int = 30, fps: float = 30.0) -> tuple[Path, Path]:
    """A small mp4 and one OpenPose JSON file per frame (one person, BODY_25)."""
    cv2 = pytest.importorskip("cv2")
    folder.mkdir(parents=True, exist_ok=True)
    video = folder / "clip.mp4"
    writer = cv2.VideoWriter(str(video), cv2.VideoWriter_fourcc(*"mp4v"), fps, (96, 64))
    assert writer.isOpened()
    for i in range(n_frames):
        writer.write(np.full((64, 96, 3), i % 256, np.uint8))
    writer.release()
    poses = folder / "clip_json"
    poses.mkdir()
    for i in range(n_frames):
        flat: list[float] = []
        for j in range(25):
            flat += [100.0 + 5.0 * i + 3 * j, 40.0 + 2 * j, 0.9]
        doc = {"version": 1.3, "people": [{"person_id": [-1], "pose_keypoints_2d": flat}]}
        (poses / f"clip_{i:012d}_keypoints.json").write_text(json.dumps(doc))
    return video, poses


def test_queued_video_ingests_of_the_same_data_commit_one_version(tmp_path):
    video, poses = _video(tmp_path / "in")
    store = tmp_path / "store"
    StoreLayout(store).ensure()
    args = ("ingest", "video", str(video), "--poses", str(poses), "--no-music")
    outs = _queued(store, tmp_path, [(*args, "--store", str(store), "-q")] * 2)
    assert sorted(outs) == [
        "ingest video: nothing to do, version v1 already holds this result\n",
        "ingest video: wrote version v1\n",
    ]
    assert StoreLayout(store).committed_versions() == ["v1"]
    _settled(store)
