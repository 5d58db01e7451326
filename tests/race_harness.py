"""Deterministic writer races with real processes: start ``dancedata`` commands, freeze one
(SIGSTOP) while it holds the store lock, queue others behind it, let it go (SIGCONT).

Shared by tests/store/test_races.py (featurize, segment, ingest behind a frozen featurize) and
tests/ingest/test_ingest_races.py (ingest behind a held lock or a frozen ingest). Nothing is mocked:
the lock is the store's real lock file, the commands are real CLI subprocesses, each in its own
session so that the signals reach only it.
"""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import time
from collections.abc import Callable
from pathlib import Path

from dancedata.store.layout import StoreLayout
from dancedata.store.lock import LOCK_FILE
from tests.helpers import REPO, popen_with_own_numba_cache

# Longest wait for any one step (a lock taken, a message printed, a process ending), seconds.
TIMEOUT_S = 120.0
WAITING = "waiting for the store lock"


def start(*args: str, stderr: Path) -> subprocess.Popen:
    """``dancedata ARGS`` in its own session (so SIGSTOP/SIGCONT reach only it); stderr goes to
    the file ``stderr``, stdout is piped."""
    with open(stderr, "w") as err:
        return popen_with_own_numba_cache(
            [sys.executable, "-m", "dancedata.cli", *args],
            cwd=REPO,
            stdout=subprocess.PIPE,
            stderr=err,
            text=True,
            start_new_session=True,
        )


def until(condition: Callable[[], bool], what: str, proc: subprocess.Popen | None = None) -> None:
    """Poll ``condition`` every 5 ms; AssertionError naming ``what`` when ``proc`` exits first
    or :data:`TIMEOUT_S` passes."""
    deadline = time.monotonic() + TIMEOUT_S
    while not condition():
        if proc is not None and proc.poll() is not None:
            raise AssertionError(f"process exited ({proc.returncode}) before {what}")
        if time.monotonic() > deadline:
            raise AssertionError(f"timed out waiting for {what}")
        time.sleep(0.005)


def lock_pid(store: Path) -> int | None:
    """The pid recorded in the store's lock file, None when there is none (yet)."""
    try:
        return json.loads((store / LOCK_FILE).read_text())["pid"]
    except (OSError, ValueError, KeyError):
        return None


def waiting(proc: subprocess.Popen, stderr: Path) -> None:
    """Return once ``proc`` has said it waits for the store lock (on ``stderr``)."""
    until(lambda: WAITING in stderr.read_text(), "the --wait message", proc)


def freeze(store: Path, *args: str, stderr: Path, what: str) -> subprocess.Popen:
    """Start ``dancedata ARGS`` and stop it (SIGSTOP) as soon as it holds ``store``'s lock,
    checking that it had not committed yet."""
    before = StoreLayout(store).committed_versions()
    proc = start(*args, stderr=stderr)
    try:
        until(lambda: lock_pid(store) == proc.pid, what, proc)
        os.killpg(proc.pid, signal.SIGSTOP)
    except BaseException:
        finish(proc)
        raise
    assert StoreLayout(store).committed_versions() == before, "froze it too late"
    return proc


def thaw(proc: subprocess.Popen) -> None:
    """Let a frozen command go on (SIGCONT)."""
    os.killpg(proc.pid, signal.SIGCONT)


def finish(proc: subprocess.Popen) -> None:
    """Clean-up: a command still running is let go and waited for, killed if it hangs."""
    if proc.poll() is None:
        thaw(proc)
        try:
            proc.wait(timeout=TIMEOUT_S)
        except subprocess.TimeoutExpired:
            os.killpg(proc.pid, signal.SIGKILL)


def queue_behind(frozen: subprocess.Popen, tmp_path: Path, *args: str) -> tuple[str, str, str]:
    """Start ``dancedata ARGS --wait`` while ``frozen`` holds the lock, let ``frozen`` finish,
    then the queued one; both must exit 0. Returns (stdout of ``frozen``, stdout and stderr of
    the queued command)."""
    err = tmp_path / "second.err"
    second = start(*args, "--wait", stderr=err)
    waiting(second, err)
    thaw(frozen)
    out_first, _ = frozen.communicate(timeout=TIMEOUT_S)
    assert frozen.returncode == 0, out_first
    out, _ = second.communicate(timeout=TIMEOUT_S)
    assert second.returncode == 0, err.read_text()
    return out_first, out, err.read_text()
