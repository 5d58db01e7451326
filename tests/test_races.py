"""No lost update (issue 11, item 3): a writer that waited for the store lock plans its version
(parent, fingerprint, "already done") only once it holds the lock.

Each race is made deterministic without mocking anything: the first writer is a real
``dancedata featurize`` subprocess, frozen with SIGSTOP as soon as it holds the store lock (its
version not yet committed); the second command is started, and the test waits until it reports
"waiting for the store lock" before letting the first one go on (SIGCONT).
"""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import time
from collections.abc import Iterator
from pathlib import Path

import pytest

from dancedata.store.layout import StoreLayout
from dancedata.store.lock import LOCK_FILE
from dancedata.store.reader import VersionReader
from dancedata.store.validate import validate_store
from dancedata.synth.aist import synth_aist
from tests.helpers import REPO, run_cli

# Motion only: the race is about versions, not features, and this keeps featurize ~1 s of work.
FEATURIZE = ("featurize", "--no-audio", "-q")
TIMEOUT_S = 120.0


@pytest.fixture(scope="module")
def raw(tmp_path_factory) -> Path:
    path = tmp_path_factory.mktemp("races") / "raw"
    synth_aist(path, n_sequences=2, seed=3)
    return path


@pytest.fixture
def store(raw: Path, tmp_path: Path) -> Path:
    path = tmp_path / "store"
    run_cli("ingest", "aist", str(raw), "--store", str(path), "-q")
    return path


def _start(*args: str, stderr: Path) -> subprocess.Popen:
    with open(stderr, "w") as err:
        return subprocess.Popen(
            [sys.executable, "-m", "dancedata.cli", *args],
            cwd=REPO,
            stdout=subprocess.PIPE,
            stderr=err,
            text=True,
            start_new_session=True,
        )


def _until(condition, what: str, proc: subprocess.Popen | None = None) -> None:
    deadline = time.monotonic() + TIMEOUT_S
    while not condition():
        if proc is not None and proc.poll() is not None:
            raise AssertionError(f"process exited ({proc.returncode}) before {what}")
        if time.monotonic() > deadline:
            raise AssertionError(f"timed out waiting for {what}")
        time.sleep(0.005)


def _lock_pid(store: Path) -> int | None:
    try:
        return json.loads((store / LOCK_FILE).read_text())["pid"]
    except (OSError, ValueError, KeyError):
        return None


@pytest.fixture
def frozen_featurize(store: Path, tmp_path: Path) -> Iterator[subprocess.Popen]:
    """A featurize run stopped (SIGSTOP) while it holds the lock, before it commits."""
    proc = _start(*FEATURIZE, str(store), stderr=tmp_path / "first.err")
    try:
        _until(lambda: _lock_pid(store) == proc.pid, "the first featurize to take the lock", proc)
        os.killpg(proc.pid, signal.SIGSTOP)
        assert StoreLayout(store).committed_versions() == ["v1"], "froze it too late"
        yield proc
    finally:
        if proc.poll() is None:
            os.killpg(proc.pid, signal.SIGCONT)
            try:
                proc.wait(timeout=TIMEOUT_S)
            except subprocess.TimeoutExpired:
                os.killpg(proc.pid, signal.SIGKILL)


def _queue_behind(frozen: subprocess.Popen, tmp_path: Path, *args: str) -> tuple[str, str]:
    """Start ``dancedata ARGS --wait`` while ``frozen`` holds the lock, let ``frozen`` finish,
    and return the second command's (stdout, stderr)."""
    err = tmp_path / "second.err"
    second = _start(*args, "--wait", stderr=err)
    _until(lambda: "waiting for the store lock" in err.read_text(), "the --wait message", second)
    os.killpg(frozen.pid, signal.SIGCONT)
    out_first, _ = frozen.communicate(timeout=TIMEOUT_S)
    assert frozen.returncode == 0, (tmp_path / "first.err").read_text()
    assert "wrote version v2" in out_first
    out, _ = second.communicate(timeout=TIMEOUT_S)
    assert second.returncode == 0, err.read_text()
    return out, err.read_text()


def test_segment_waiting_behind_featurize_keeps_the_features(frozen_featurize, store, tmp_path):
    out, _ = _queue_behind(frozen_featurize, tmp_path, "segment", str(store), "-q")
    assert "wrote version v3" in out
    layout = StoreLayout(store)
    assert layout.latest() == "v3"
    latest = VersionReader(store)
    # The segment version derives from the featurize result, not from v1 as planned earlier.
    assert latest.manifest["parent"] == "v2"
    assert set(latest.manifest["stages"]) == {"ingest", "featurize", "segment"}
    assert latest.has_array("motion/quat") and latest.has_array("motion/rot6d")
    assert latest.table("measures").num_rows > 0
    assert validate_store(store) == []


def test_second_featurize_waiting_behind_the_same_featurize_writes_nothing(
    frozen_featurize, store, tmp_path
):
    out, _ = _queue_behind(frozen_featurize, tmp_path, *FEATURIZE, str(store))
    assert "nothing to do, version v2 already holds this result" in out
    assert StoreLayout(store).committed_versions() == ["v1", "v2"]
    assert StoreLayout(store).temp_dirs() == []
    assert not (store / LOCK_FILE).exists()


def test_second_ingest_of_the_same_data_waiting_for_the_lock_adds_no_duplicate(
    raw, store, tmp_path
):
    """Ingest plans before the lock (it reads its inputs first); the writer still finds the
    result committed by the writer it waited for and commits nothing."""
    other = tmp_path / "raw2"
    synth_aist(other, n_sequences=2, seed=4)
    holder = _start(*FEATURIZE, str(store), stderr=tmp_path / "first.err")
    try:
        _until(lambda: _lock_pid(store) == holder.pid, "featurize to take the lock", holder)
        os.killpg(holder.pid, signal.SIGSTOP)
        errs = [tmp_path / "ingest-a.err", tmp_path / "ingest-b.err"]
        ingests = [
            _start("ingest", "aist", str(other), "--store", str(store), "--wait", "-q", stderr=e)
            for e in errs
        ]
        for proc, err in zip(ingests, errs, strict=True):
            _until(lambda err=err: "waiting for the store lock" in err.read_text(), "wait", proc)
    finally:
        os.killpg(holder.pid, signal.SIGCONT)
    holder.communicate(timeout=TIMEOUT_S)
    outs = [p.communicate(timeout=TIMEOUT_S)[0] for p in ingests]
    assert [p.returncode for p in ingests] == [0, 0], [e.read_text() for e in errs]
    committed = StoreLayout(store).committed_versions()
    assert committed == ["v1", "v2", "v3"], (committed, outs)  # v2 featurize, v3 one ingest
    fingerprints = [StoreLayout(store).read_manifest(v)["fingerprint"] for v in committed]
    assert len(set(fingerprints)) == len(fingerprints)
    assert all("v3" in out for out in outs)


def test_a_writer_based_on_a_version_that_is_no_longer_latest_refuses(store):
    """``based_on`` (for commands that read the latest version's data before the lock, such as
    an append): once another writer has committed, the write is refused with one line instead
    of dropping that writer's version; the store is left as it was."""
    from dancedata.errors import StoreError
    from dancedata.pipeline.segment import SegmentOptions, segment
    from dancedata.store.writer import VersionWriter

    read_before_the_lock = StoreLayout(store).latest()
    assert segment(store, SegmentOptions()).version == "v2"  # another writer got in first
    writer = VersionWriter(
        store,
        command="test",
        config={},
        fingerprint="f" * 64,
        parent="v1",
        carry_over=False,
        based_on=read_before_the_lock,
    )
    changed = "read v1, the latest version is now v2; run it again"
    with pytest.raises(StoreError, match=changed), writer:
        pass
    assert StoreLayout(store).committed_versions() == ["v1", "v2"]
    assert StoreLayout(store).temp_dirs() == []
    assert not (store / LOCK_FILE).exists()
    with VersionWriter(
        store, command="test", config={}, fingerprint="f" * 64, parent="v2", based_on="v2"
    ) as version:
        assert version.commit() == "v3"
