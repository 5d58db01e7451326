"""One writer per store: a second writer fails clearly or waits; a crashed holder's lock is taken
over (same host, holder provably gone) but a lock from another host never is; readers never see a
partial version, even while a commit is in progress."""

from __future__ import annotations

import json
import os
import signal
import socket
import subprocess
import sys
import textwrap
import time
from pathlib import Path

import pytest

import dancedata
from dancedata.errors import StoreError
from dancedata.ingest.aist import AistIngestOptions, ingest_aist
from dancedata.store.integrity import check_record
from dancedata.store.layout import StoreLayout
from dancedata.store.lock import (
    LOCK_FILE,
    StoreLock,
    boot_id,
    judge_holder,
    process_start_ticks,
    this_holder,
)
from dancedata.store.unlock import unlock
from dancedata.store.validate import validate_store, validate_version
from dancedata.synth.aist import synth_aist
from tests.helpers import REPO, run_cli

# slow: lock holders and waiters in subprocesses, with timeouts
pytestmark = pytest.mark.slow

_HOLD = textwrap.dedent(
    """
    import sys
    from dancedata.store.lock import StoreLock
    lock = StoreLock(sys.argv[1], command="test holder")
    lock.acquire()
    print("held", flush=True)
    sys.stdin.readline()          # release when the test says so (or die by SIGKILL)
    lock.release()
    """
)


def _popen(code: str, *args: str, **kwargs) -> subprocess.Popen:
    return subprocess.Popen(
        [sys.executable, "-c", code, *args],
        cwd=REPO,
        text=True,
        start_new_session=True,
        **kwargs,
    )


def _hold(root: Path) -> subprocess.Popen:
    """A process that holds the store lock until a line arrives on its stdin."""
    proc = _popen(_HOLD, str(root), stdin=subprocess.PIPE, stdout=subprocess.PIPE)
    assert proc.stdout.readline().strip() == "held"
    return proc


def _write_lock(root: Path, **fields) -> dict:
    record = {**this_holder("forged"), **fields}
    (root / LOCK_FILE).write_text(json.dumps(record), encoding="utf-8")
    return record


@pytest.fixture(scope="module")
def raw(tmp_path_factory) -> Path:
    path = tmp_path_factory.mktemp("lockraw") / "raw"
    synth_aist(path, n_sequences=3, seed=11)
    return path


@pytest.fixture
def store(tmp_path, raw) -> Path:
    path = tmp_path / "store"
    ingest_aist(path, raw, AistIngestOptions())
    return path


# -- a second writer ---------------------------------------------------------------------------
def test_second_writer_fails_with_one_clear_line_naming_the_holder(store):
    holder = _hold(store)
    try:
        proc = run_cli("segment", str(store), "-q", check=False)
        assert proc.returncode == 1
        lines = proc.stderr.strip().splitlines()
        assert len(lines) == 1, proc.stderr
        assert "store is locked by another writer" in lines[0]
        assert f"pid {holder.pid} on host {socket.gethostname()}" in lines[0]
        assert "test holder" in lines[0] and "--wait" in lines[0]
        assert StoreLayout(store).committed_versions() == ["v1"]
    finally:
        holder.communicate("go\n", timeout=30)
    assert not (store / LOCK_FILE).exists()


def test_second_writer_with_wait_says_so_then_commits_after_release(store):
    holder = _hold(store)
    waiter = subprocess.Popen(
        [sys.executable, "-m", "dancedata.cli", "segment", str(store), "-q", "--wait"],
        cwd=REPO,
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
        start_new_session=True,
    )
    try:
        first = waiter.stderr.readline()
        assert first.startswith("waiting for the store lock: store is locked by another writer")
        assert f"pid {holder.pid}" in first
        time.sleep(0.5)
        assert waiter.poll() is None, "the waiting writer must not give up"
        assert StoreLayout(store).committed_versions() == ["v1"]
    finally:
        holder.communicate("go\n", timeout=30)
    out, err = waiter.communicate(timeout=120)
    assert waiter.returncode == 0, err
    assert "wrote version v2" in out
    assert validate_store(store) == []


# -- stale, recycled and foreign locks ---------------------------------------------------------
def test_lock_of_a_killed_holder_survives_and_is_taken_over_by_the_next_writer(store, capfd):
    holder = _hold(store)
    os.killpg(holder.pid, signal.SIGKILL)
    holder.wait()
    left = json.loads((store / LOCK_FILE).read_text())
    assert left["pid"] == holder.pid  # the lock outlives its holder ...
    assert judge_holder(left).status == "stale"
    with StoreLock(store) as lock:  # ... and the next writer takes it over
        assert [h["pid"] for h in lock.took_over] == [holder.pid]
    assert "took over a stale store lock" in capfd.readouterr().err
    assert not (store / LOCK_FILE).exists()


def test_a_recycled_pid_does_not_keep_a_dead_writers_lock(store):
    # Our own (live) pid, but a different process start time: the pid was reused.
    ticks = process_start_ticks(os.getpid())
    if ticks is None:
        pytest.skip("no /proc: process start times unavailable")
    _write_lock(store, pid=os.getpid(), start_ticks=ticks + 12345)
    assert judge_holder(json.loads((store / LOCK_FILE).read_text())).status == "stale"
    with StoreLock(store) as lock:
        assert len(lock.took_over) == 1


def test_a_lock_from_before_a_reboot_is_stale(store):
    if boot_id() is None:
        pytest.skip("no boot id on this platform")
    _write_lock(store, pid=os.getpid(), boot_id="00000000-0000-0000-0000-000000000000")
    with StoreLock(store) as lock:
        assert len(lock.took_over) == 1


def test_a_live_holder_on_this_host_is_never_taken_over(store):
    _write_lock(store)  # this very process, alive, same start time
    assert judge_holder(json.loads((store / LOCK_FILE).read_text())).status == "live"
    with pytest.raises(StoreError, match="locked by another writer"):
        StoreLock(store).acquire()
    with pytest.raises(StoreError, match="held by a running writer"):
        unlock(store)
    assert (store / LOCK_FILE).exists()


def test_a_lock_from_another_host_is_never_taken_over_automatically(store):
    # pid 1 exists here too, which must not matter: the holder ran on another machine.
    _write_lock(store, host="render-node-7", pid=1, boot_id="x", start_ticks=1)
    proc = run_cli("segment", str(store), "-q", check=False)
    assert proc.returncode == 1
    line = proc.stderr.strip()
    assert "\n" not in line
    assert "render-node-7" in line and "never taken over automatically" in line
    assert f"dancedata unlock {store} --force" in line
    lock = StoreLock(store, wait=True, timeout_s=0.5)
    with pytest.raises(StoreError, match="gave up waiting"):
        lock.acquire()
    assert (store / LOCK_FILE).exists()
    # How to clear it: `dancedata unlock STORE --force` (refused without --force).
    refused = run_cli("unlock", str(store), check=False)
    assert refused.returncode == 1 and "--force" in refused.stderr
    cleared = run_cli("unlock", str(store), "--force")
    assert "removed the lock of pid 1 on host render-node-7" in cleared.stdout
    assert "wrote version v2" in run_cli("segment", str(store), "-q").stdout


def test_an_unreadable_lock_file_is_reported_not_silently_removed(store, monkeypatch):
    """A lock file that is not a record is waited on while it is young (a writer without hard
    links may be filling it: ``_FRESH_S``, shortened here from 5 s), then reported, never
    removed; an old one is reported at once."""
    import dancedata.store.lock as lock_module

    monkeypatch.setattr(lock_module, "_FRESH_S", 1.0)
    (store / LOCK_FILE).write_text("garbage", encoding="utf-8")
    started = time.monotonic()
    with pytest.raises(StoreError, match="not a dancedata lock record"):
        StoreLock(store).acquire()
    assert time.monotonic() - started >= 0.8  # waited while the file was young
    assert (store / LOCK_FILE).read_text() == "garbage"
    old = time.time() - 60
    os.utime(store / LOCK_FILE, (old, old))
    started = time.monotonic()
    with pytest.raises(StoreError, match="not a dancedata lock record"):
        StoreLock(store).acquire()
    assert time.monotonic() - started < 0.8  # an old file: no wait
    assert (store / LOCK_FILE).read_text() == "garbage"
    assert "unreadable lock file" in unlock(store, force=True)


def test_unlock_clears_a_stale_lock_and_reports_an_unlocked_store(store):
    dead = subprocess.run(
        [sys.executable, "-c", "import os; print(os.getpid())"],
        capture_output=True,
        text=True,
        check=True,
    )
    _write_lock(store, pid=int(dead.stdout), start_ticks=None)
    assert "no longer exists" in unlock(store)
    assert "is not locked" in unlock(store)


# -- races -------------------------------------------------------------------------------------
_CONTEND = textwrap.dedent(
    """
    import os, sys, time
    from pathlib import Path
    from dancedata.store.lock import StoreLock
    root, rounds = Path(sys.argv[1]), int(sys.argv[2])
    inside = root / "inside"
    for _ in range(rounds):
        with StoreLock(root, wait=True):
            fd = os.open(inside, os.O_CREAT | os.O_EXCL | os.O_WRONLY)  # fails if shared
            os.close(fd)
            time.sleep(0.002)
            inside.unlink()
    print("ok", flush=True)
    """
)


def test_contending_writers_breaking_a_stale_lock_never_overlap(tmp_path):
    """Six processes race for a lock that starts stale (a dead pid): at most one is ever inside
    (each inside-marker is created with O_EXCL), and every round of every process finishes."""
    root = tmp_path / "contended"
    root.mkdir()
    dead = subprocess.run(
        [sys.executable, "-c", "import os; print(os.getpid())"],
        capture_output=True,
        text=True,
        check=True,
    )
    _write_lock(root, pid=int(dead.stdout), start_ticks=None)
    procs = [
        _popen(_CONTEND, str(root), "15", stdout=subprocess.PIPE, stderr=subprocess.PIPE)
        for _ in range(6)
    ]
    for proc in procs:
        out, err = proc.communicate(timeout=120)
        assert proc.returncode == 0 and out.strip() == "ok", err
    assert not (root / LOCK_FILE).exists()


_COMMIT_LOOP = textwrap.dedent(
    """
    import sys
    from dancedata.store.contract import build_table
    from dancedata.store.layout import StoreLayout
    from dancedata.store.reader import _VersionReader
    from dancedata.store.writer import VersionWriter
    store, n = sys.argv[1], int(sys.argv[2])
    seqs = _VersionReader(store).table("sequences").to_pylist()
    for i in range(n):
        rows = [
            {"seq_id": s["seq_id"], "measure": 0, "frame_start": 0, "frame_stop": 1 + i,
             "time_start": 0.0, "time_stop": (1 + i) / 60.0, "bpm": 100.0}
            for s in seqs
        ]
        parent = StoreLayout(store).latest()
        with VersionWriter(store, command="test-commit", config={"i": i}, fingerprint=f"fp{i}",
                           parent=parent, wait_for_lock=True) as v:
            v.write_table("measures", build_table("measures", rows))
            v.commit(counts={"i": i})
    print("done", flush=True)
    """
)


def test_readers_polling_during_commits_only_ever_see_complete_versions(store):
    """A reader opens the store in a tight loop while a writer commits 12 versions: every open
    succeeds, shows a complete version (manifest, checksums and contents agree) and the latest
    version never goes backwards."""
    writer = _popen(_COMMIT_LOOP, str(store), "12", stdout=subprocess.PIPE, stderr=subprocess.PIPE)
    seen: list[str] = []
    opens = 0
    while writer.poll() is None or opens == 0:
        opened = dancedata.open_store(str(store))
        opens += 1
        manifest = opened.manifest
        assert manifest["version"] == opened.version
        assert check_record(opened.path / "versions" / opened.version, deep=True) == []
        if manifest["command"] == "test-commit":
            i = manifest["counts"]["i"]
            stops = set(opened.measures.column("frame_stop").to_pylist())
            assert stops == {1 + i}, (opened.version, stops)
        if opens % 5 == 0:
            assert validate_version(opened._reader) == []
        if seen:
            assert int(opened.version[1:]) >= int(seen[-1][1:]), (seen[-1], opened.version)
        seen.append(opened.version)
    out, err = writer.communicate(timeout=60)
    assert writer.returncode == 0 and out.strip() == "done", err
    assert StoreLayout(store).committed_versions() == [f"v{k}" for k in range(1, 14)]
    assert len(set(seen)) >= 3, f"the reader saw too few versions to mean anything: {set(seen)}"
    assert validate_store(store) == []


def test_lock_temporaries_of_dead_writers_are_cleaned_by_the_next_writer(store):
    dead = subprocess.run(
        [sys.executable, "-c", "import os; print(os.getpid())"],
        capture_output=True,
        text=True,
        check=True,
    )
    here = store / f"{LOCK_FILE}.{socket.gethostname()}.{int(dead.stdout)}.abcd.tmp"
    alive = store / f"{LOCK_FILE}.{socket.gethostname()}.{os.getpid()}.beef.tmp"
    remote = store / f"{LOCK_FILE}.render-node-7.{int(dead.stdout)}.cafe.tmp"
    for path in (here, alive, remote):
        path.write_text("{}")
    with StoreLock(store):
        pass
    assert not here.exists()
    assert alive.exists() and remote.exists()  # a live writer's, another host's: left alone
