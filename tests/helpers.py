"""Small helpers shared by tests (not fixtures)."""

from __future__ import annotations

import contextlib
import io
import os
import signal
import subprocess
import sys
import warnings
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]


def run_cli(
    *args: str,
    check: bool = True,
    env: dict[str, str] | None = None,
    timeout: float | None = None,
    isolated: bool = False,
) -> subprocess.CompletedProcess:
    """Run ``dancedata ARGS`` and return its exit code, stdout and stderr.

    In this interpreter by default (:func:`run_cli_in_process`): the command's own code path,
    without the ~1 s of interpreter start and imports a subprocess pays per call. With a
    ``timeout`` (a hang must end in a failure, not stall the suite), in a process of its own
    forked from a server that imported the command line once (tests/fork_server.py). In a fresh
    subprocess of this interpreter (:func:`run_cli_subprocess`) with ``isolated=True`` or an
    ``env`` (start-up variables such as PATH or PYTHONPATH, credentials that cached filesystem
    objects would not see)."""
    if isolated or env is not None:
        proc = run_cli_subprocess(*args, env=env, timeout=600 if timeout is None else timeout)
    elif timeout is not None:
        from tests.fork_server import run_forked

        proc = run_forked(list(args), timeout=timeout)
    else:
        proc = run_cli_in_process(*args)
    if check and proc.returncode != 0:
        raise AssertionError(
            f"dancedata {' '.join(args)} exited {proc.returncode}\n"
            f"stdout:\n{proc.stdout}\nstderr:\n{proc.stderr}"
        )
    return proc


def run_cli_subprocess(
    *args: str, env: dict[str, str] | None = None, timeout: float = 600
) -> subprocess.CompletedProcess:
    """``python -m dancedata.cli ARGS`` in a subprocess with this interpreter."""
    return subprocess.run(
        [sys.executable, "-m", "dancedata.cli", *args],
        capture_output=True,
        text=True,
        env={**os.environ, **(env or {})},
        timeout=timeout,
    )


def _text_of(stream: io.BytesIO) -> str:
    """What ``subprocess.run(text=True)`` makes of the bytes: UTF-8, universal newlines."""
    return stream.getvalue().decode("utf-8").replace("\r\n", "\n").replace("\r", "\n")


def run_cli_in_process(*args: str) -> subprocess.CompletedProcess:
    """``dancedata ARGS`` through :func:`dancedata.cli.main.exit_code` in this interpreter.

    What a subprocess would see is reproduced: ``sys.argv``; stdout and stderr as UTF-8 text
    streams that are not terminals, read back as ``subprocess.run(text=True)`` would; warnings
    printed to that stderr under a fresh interpreter's filters (not collected by pytest); the
    process-wide quiet flag, the environment, the working folder and the signal handlers put
    back afterwards."""
    from dancedata.cli.main import exit_code

    from dancedata.progress import set_quiet

    out, err = io.BytesIO(), io.BytesIO()
    stdout = io.TextIOWrapper(out, encoding="utf-8", write_through=True)
    stderr = io.TextIOWrapper(err, encoding="utf-8", write_through=True)
    saved_argv, saved_env, saved_cwd = sys.argv, dict(os.environ), os.getcwd()
    saved_handlers = {sig: signal.getsignal(sig) for sig in (signal.SIGINT, signal.SIGTERM)}

    def show(message, category, filename, lineno, file=None, line=None) -> None:  # noqa: ANN001
        stderr.write(warnings.formatwarning(message, category, filename, lineno, line))

    sys.argv = ["dancedata", *args]
    try:
        with (
            contextlib.redirect_stdout(stdout),
            contextlib.redirect_stderr(stderr),
            warnings.catch_warnings(),
        ):
            warnings.resetwarnings()  # then the filters a fresh `python` starts with
            for category in (ResourceWarning, ImportWarning, PendingDeprecationWarning):
                warnings.simplefilter("ignore", category)
            warnings.simplefilter("ignore", DeprecationWarning)
            warnings.filterwarnings("default", category=DeprecationWarning, module="__main__")
            warnings.showwarning = show
            code = exit_code()
            stdout.flush()
            stderr.flush()
    finally:
        sys.argv = saved_argv
        if os.environ != saved_env:
            os.environ.clear()
            os.environ.update(saved_env)
        os.chdir(saved_cwd)
        for sig, handler in saved_handlers.items():
            if handler is not None:
                signal.signal(sig, handler)
        set_quiet(False)
    return subprocess.CompletedProcess(["dancedata", *args], code, _text_of(out), _text_of(err))


def importorskip_unless_ci(name: str):  # noqa: ANN201 - the imported module
    """``pytest.importorskip(name)``, except that under ``CI=true`` (where the Makefile's test
    target installs every optional extra) a missing module fails the test instead of skipping."""
    import importlib

    import pytest

    try:
        return importlib.import_module(name)
    except ImportError as exc:
        if os.environ.get("CI", "").lower() == "true":
            pytest.fail(f"CI=true but {name} is not installed ({exc}); run `make test`")
        pytest.skip(f"{name} not installed: {exc}", allow_module_level=True)


# Processes a test keeps running side by side, by numba cache slot (see ``own_numba_cache``).
_NUMBA_SLOTS: dict[int, subprocess.Popen] = {}


def _free_numba_slot() -> int:
    """The lowest numba cache slot no running process started by ``popen_with_own_numba_cache``
    holds."""
    slot = 0
    while slot in _NUMBA_SLOTS and _NUMBA_SLOTS[slot].poll() is None:
        slot += 1
    return slot


def own_numba_cache(env: dict[str, str], name: str) -> dict[str, str]:
    """``env`` with a numba cache folder of its own, ``<this worker's folder>/<name>``.

    Processes that run at the same time must not share one (two processes compiling the same
    gufunc into one folder leave a pair of files that segfaults every later process reading it,
    numba issue 10128; tests/conftest.py gives each xdist worker its folder, which every process
    the worker starts inherits). Named, not temporary, so the compile is paid once per machine;
    a new folder starts as a copy of what this worker compiled so far (seed_cache_folder), so on
    a machine with no cache it is not paid again for each folder."""
    from dancedata.exec.numba_cache import seed_cache_folder, seed_sources

    base = os.environ.get("NUMBA_CACHE_DIR")
    if not base:
        return env
    seed_cache_folder(Path(base) / name, seed_sources(Path(base)))
    return {**env, "NUMBA_CACHE_DIR": str(Path(base) / name)}


def popen_with_own_numba_cache(argv: list[str], **kwargs) -> subprocess.Popen:
    """``subprocess.Popen(argv, **kwargs)`` in a numba cache slot no running process of this
    helper holds (a process started while another runs gets the next slot)."""
    slot = _free_numba_slot()
    env = kwargs.pop("env", None) or dict(os.environ)
    proc = subprocess.Popen(argv, env=own_numba_cache(env, f"concurrent-{slot}"), **kwargs)
    _NUMBA_SLOTS[slot] = proc
    return proc
