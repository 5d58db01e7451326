"""Commands in processes of their own, without paying the interpreter's start each time.

The hostile corpus and the tests that bound a command's time run a few thousand commands, each
in a process of its own: a hang must end in a kill, a peak resident set must be the command's
own, a crash must not take pytest with it. A fresh ``python -m dancedata.cli`` spends about a
second starting and importing before the command does anything, which was most of those
tests' time. :class:`ForkServer` starts one server process per pytest worker that imports the
command line and the whole library (all but the torch loaders; see ``SERVER``) once, then
forks one child per command. The child is a
process of its own, as before: its own session (killed with its children on timeout), the
case's working folder and environment, stdin from /dev/null, stdout and stderr into files, and
it ends through ``dancedata.cli.main.run`` like the ``dancedata`` program. Its peak RSS
(``VmHWM``, written at exit) counts the pages it shares with the server, which imported more
than most commands need, so the memory bound is stricter, not looser.

:meth:`ForkServer.run` waits for the child (killing it at a timeout); :meth:`ForkServer.spawn`
returns at once with a :class:`ForkedProcess` that answers ``poll()`` and ``wait()`` like
``subprocess.Popen``, for tests that signal the command themselves (the kill loop of
tests/cli/test_kill_loop.py). Either way the server replies only once the child leads a
process group of its own, so a ``killpg`` right after never misses it.

Only variables read at run time may differ between commands: the server's imports read none of
the ones the tests change (the feature cache, credentials) except ``MPLCONFIGDIR``, which
matplotlib reads once at import: a child uses the server's font cache, whatever its own
``MPLCONFIGDIR`` says (so it writes none). A test that needs a different start-up environment
(PATH, PYTHONPATH, matplotlib's configuration) uses a plain subprocess.
"""

from __future__ import annotations

import atexit
import json
import os
import subprocess
import sys
from dataclasses import dataclass
from pathlib import Path

from tests.helpers import REPO

SERVER = r"""
import json, os, signal, sys, time

sys.argv = ["dancedata"]
import importlib, pkgutil
import numpy, pyarrow, pyarrow.parquet, zarr  # noqa: E401,F401 - what every command imports
import dancedata
from dancedata.cli.main import build_command, run

build_command()  # every command module, and the command tree each child reuses
# Every library module but the torch loaders, and the heavy imports the commands make lazily
# (pandas through pyarrow, pydantic through typer's parameter adapters, matplotlib's figure
# and font list, librosa and numba through the library): a child then starts with them
# imported. Its VmHWM counts them all, so the memory bound gets stricter, not looser.
for info in pkgutil.walk_packages(dancedata.__path__, "dancedata."):
    if "torch" not in info.name:
        importlib.import_module(info.name)
import pandas, typer._adapters, matplotlib.figure, matplotlib.backends.backend_agg  # noqa
import matplotlib.font_manager  # noqa: F401 - the font list, read once here
assert "torch" not in sys.modules, "a preloaded module imports torch"
# Every object imported so far goes to the collector's permanent generation: a child's full
# collections then skip them, instead of writing to the header of each and so copying most of
# the server's heap page by page (measured on the hostile corpus, 653 commands: 94-98 -> 74 CPU s
# in the children). What the child's command does is the same, and so is its VmHWM (mean 170 MiB
# either way, the largest 269 MiB against 277).
import gc

gc.freeze()
requests = os.fdopen(os.dup(0), "r")
replies = os.fdopen(os.dup(1), "w")
devnull = os.open(os.devnull, os.O_RDONLY)


def vm_hwm(pid):
    try:
        with open(f"/proc/{pid}/status") as fh:
            return int(fh.read().split("VmHWM:")[1].split()[0]) * 1024
    except (OSError, IndexError, ValueError):
        return 0


def child(req, ready):
    os.setsid()
    os.write(ready, b"1")  # a group of its own now: the parent may reply, a kill finds it
    os.close(ready)
    os.chdir(req["cwd"])
    os.environ.clear()
    os.environ.update(req["env"])
    flags = os.O_WRONLY | os.O_CREAT | os.O_TRUNC
    out, err = os.open(req["stdout"], flags, 0o644), os.open(req["stderr"], flags, 0o644)
    os.dup2(devnull, 0)
    os.dup2(out, 1)
    os.dup2(err, 2)
    for fd in (out, err, devnull, requests.fileno(), replies.fileno()):
        os.close(fd)
    peak_file = req.get("peak")

    def peak():
        with open("/proc/self/status") as fh:
            kb = fh.read().split("VmHWM:")[1].split()[0]
        with open(peak_file, "w") as fh:
            fh.write(kb)

    if peak_file:
        import atexit

        atexit.register(peak)
    sys.argv = ["dancedata", *req["argv"]]
    run()


def start(req):
    # fork the child of req; return once it leads a process group of its own
    sys.stdout.flush()
    sys.stderr.flush()
    ready_r, ready_w = os.pipe()
    pid = os.fork()
    if pid == 0:
        try:
            os.close(ready_r)
            child(req, ready_w)
        finally:
            os._exit(70)
    os.close(ready_w)
    os.read(ready_r, 1)  # b"" if the child died first: nothing left to wait for
    os.close(ready_r)
    return pid


def reply(**fields):
    replies.write(json.dumps(fields) + "\n")
    replies.flush()


def finished(status, usage):
    return {"code": os.waitstatus_to_exitcode(status), "cpu": usage.ru_utime + usage.ru_stime}


spawned = set()  # children started by "spawn", reaped by "poll" or "wait"
for line in requests:
    req = json.loads(line)
    mode = req.get("mode", "run")
    if mode == "spawn":
        pid = start(req)
        spawned.add(pid)
        reply(pid=pid)
        continue
    if mode in ("poll", "wait"):
        pid = req["pid"]
        if pid not in spawned:
            reply(error=f"no spawned child {pid}")
            continue
        got, status, usage = os.wait4(pid, os.WNOHANG if mode == "poll" else 0)
        if not got:
            reply(code=None, running=True)
            continue
        spawned.discard(pid)
        reply(**finished(status, usage), running=False)
        continue
    pid = start(req)
    deadline = time.monotonic() + req["timeout"]
    code, polled = None, 0
    while True:
        got, status, usage = os.wait4(pid, os.WNOHANG)
        if got:
            code = os.waitstatus_to_exitcode(status)
            break
        polled = max(polled, vm_hwm(pid))
        if time.monotonic() > deadline:
            try:
                os.killpg(pid, signal.SIGKILL)
            except ProcessLookupError:
                pass
            _, status, usage = os.wait4(pid, 0)
            break
        time.sleep(0.02)
    reply(code=code, cpu=usage.ru_utime + usage.ru_stime, polled=polled)
for pid in spawned:  # the tests ended without waiting: leave no orphan running
    try:
        os.killpg(pid, signal.SIGKILL)
    except ProcessLookupError:
        pass
    os.waitpid(pid, 0)
"""


@dataclass
class Finished:
    """What one command did: exit code (None when killed at its timeout), CPU seconds of the
    child, peak RSS in bytes polled while it ran (the child's own figure is in its peak file)."""

    code: int | None
    cpu_s: float
    polled_rss: int


class ForkServer:
    """One server process (started on first use, ended at exit) forking a child per command."""

    def __init__(self) -> None:
        self._proc: subprocess.Popen | None = None

    def _server(self) -> subprocess.Popen:
        if self._proc is None or self._proc.poll() is not None:
            env = {**os.environ, "PYTHONPATH": str(REPO)}
            self._proc = subprocess.Popen(
                [sys.executable, "-c", SERVER],
                stdin=subprocess.PIPE,
                stdout=subprocess.PIPE,
                text=True,
                env=env,
                cwd=REPO,
            )
            atexit.register(self.close)
        return self._proc

    def run(
        self,
        argv: list[str],
        *,
        cwd: Path,
        env: dict[str, str],
        stdout: Path,
        stderr: Path,
        timeout: float,
        peak: Path | None = None,
    ) -> Finished:
        """Run ``dancedata ARGV`` in a forked child and wait for it (or kill it at ``timeout``
        seconds)."""
        request = {
            "argv": list(argv),
            "cwd": str(cwd),
            "env": dict(env),
            "stdout": str(stdout),
            "stderr": str(stderr),
            "timeout": float(timeout),
            "peak": str(peak) if peak else None,
        }
        record = self._ask(request)
        return Finished(record["code"], record["cpu"], record["polled"])

    def spawn(
        self, argv: list[str], *, cwd: Path, env: dict[str, str], stdout: Path, stderr: Path
    ) -> ForkedProcess:
        """Start ``dancedata ARGV`` in a forked child and return at once, the child already
        leading a process group of its own (``os.killpg(child.pid, ...)`` reaches it)."""
        request = {
            "mode": "spawn",
            "argv": list(argv),
            "cwd": str(cwd),
            "env": dict(env),
            "stdout": str(stdout),
            "stderr": str(stderr),
        }
        return ForkedProcess(self, self._ask(request)["pid"])

    def _ask(self, request: dict) -> dict:
        """Send one request, return the server's reply."""
        server = self._server()
        assert server.stdin is not None and server.stdout is not None
        server.stdin.write(json.dumps(request) + "\n")
        server.stdin.flush()
        reply = server.stdout.readline()
        if not reply:
            raise RuntimeError(f"the fork server ended (exit {server.wait()})")
        record = json.loads(reply)
        if "error" in record:
            raise RuntimeError(record["error"])
        return record

    def close(self) -> None:
        if self._proc is not None and self._proc.poll() is None:
            assert self._proc.stdin is not None
            self._proc.stdin.close()
            try:
                self._proc.wait(timeout=10)
            except subprocess.TimeoutExpired:
                self._proc.kill()
        self._proc = None


class ForkedProcess:
    """A child started by :meth:`ForkServer.spawn`, answering as ``subprocess.Popen`` does:
    ``poll()`` and ``wait()`` give the exit code (negative: the signal that ended it), which
    the server reaps, as the child is the server's."""

    def __init__(self, server: ForkServer, pid: int) -> None:
        self._server = server
        self.pid = pid
        self.returncode: int | None = None

    def _ask(self, mode: str) -> int | None:
        if self.returncode is None:
            record = self._server._ask({"mode": mode, "pid": self.pid})
            if not record["running"]:
                self.returncode = record["code"]
        return self.returncode

    def poll(self) -> int | None:
        return self._ask("poll")

    def wait(self) -> int:
        code = self._ask("wait")
        assert code is not None
        return code


SERVER_OF_THIS_PROCESS = ForkServer()


def run_forked(
    argv: list[str], *, timeout: float, cwd: Path | None = None, env: dict[str, str] | None = None
) -> subprocess.CompletedProcess:
    """``dancedata ARGV`` in a forked child of the server, as ``subprocess.run(text=True)``
    would report it; a command killed at its timeout raises ``subprocess.TimeoutExpired``."""
    import tempfile

    with tempfile.TemporaryDirectory(prefix="dancedata-forked-") as io_dir:
        out, err = Path(io_dir) / "stdout", Path(io_dir) / "stderr"
        done = SERVER_OF_THIS_PROCESS.run(
            argv,
            cwd=cwd or Path.cwd(),
            env=env if env is not None else dict(os.environ),
            stdout=out,
            stderr=err,
            timeout=timeout,
        )
        text = [
            p.read_bytes().decode("utf-8").replace("\r\n", "\n").replace("\r", "\n")
            for p in (out, err)
        ]
    if done.code is None:
        raise subprocess.TimeoutExpired(["dancedata", *argv], timeout, text[0], text[1])
    return subprocess.CompletedProcess(["dancedata", *argv], done.code, text[0], text[1])
