"""The runner of the hostile cases of ``tests/data/bad/hostile_*.py`` against the real command
line (``tests/cli/test_hostile_inputs.py`` and ``tests/cli/test_hostile_inputs_files.py`` each run a
share of the classes, so pytest-xdist spreads the corpus over its workers).

Each case gets its own folder holding a fresh copy of one small featurized store (copied, never
hard-linked: a case may edit files in place), a ``work`` folder for its planted files, an empty
``cwd`` the commands run in and a feature cache. Each command runs as the ``dancedata`` command
in a process of its own (forked by this worker's server, ``tests/fork_server.py``, which imported
the command line once; the child ends through ``dancedata.cli.main.run``, in its own session,
killed with its children on timeout), then again with ``--json`` when the case asks.
It fails on

* a traceback anywhere in the output, an exit code other than 0 or 1 or other than the case's,
  an error not matching the case's regular expression, more than 20 kB of output;
* under ``--json``: stdout that is not one JSON object (the error is looked for in its
  ``error``, or in the whole object for a command's own failing summary such as ``validate``);
* a hang (the case's timeout);
* any file created, changed or removed in the case folder outside the store copy, the cache and
  the command's declared output folder (the planted files and the ``cwd`` included), or in the
  folder holding the case folders;
* a peak resident set above 1 GB: the child's own ``VmHWM``, written by the wrapper at exit
  (``ru_maxrss`` would not do: it keeps the forking pytest's size across ``exec``).

``HOSTILE_RECORD=file.jsonl`` appends one line per command run (case, argv, exit, first line of
the error, peak RSS, CPU seconds, files written outside) for before/after tables.
``HOSTILE_STORE=DIR`` uses an already built featurized store instead of building one.
"""

from __future__ import annotations

import json
import os
import re
import shutil
import time
from pathlib import Path

import pytest

from tests.data.bad.hostile import Command, HostileCase, all_cases
from tests.fork_server import SERVER_OF_THIS_PROCESS
from tests.helpers import REPO

CASES = all_cases()
MAX_RSS_BYTES = 1 << 30
MAX_OUTPUT_BYTES = 20_000


def _snapshot(root: Path, skip: set[Path]) -> dict[str, tuple]:
    """relative path → (kind, size, mtime_ns) of everything under ``root`` but ``skip``."""
    found: dict[str, tuple] = {}
    for dirpath, dirnames, filenames in os.walk(root):
        here = Path(dirpath)
        dirnames[:] = [d for d in dirnames if here / d not in skip]
        for name in dirnames + filenames:
            path = here / name
            if path in skip:
                continue
            st = path.lstat()
            kind = "dir" if path.is_dir() and not path.is_symlink() else "file"
            found[os.fsdecode(path.relative_to(root))] = (
                kind,
                0 if kind == "dir" else st.st_size,
                0 if kind == "dir" else st.st_mtime_ns,
            )
    return found


def _changed(before: dict[str, tuple], after: dict[str, tuple]) -> list[str]:
    return sorted(k for k in set(before) | set(after) if before.get(k) != after.get(k))


def _run(argv: list[str], cwd: Path, env: dict[str, str], io_dir: Path, timeout: float
         ) -> tuple[int | None, str, str, int, float]:  # fmt: skip
    """(exit code or None on timeout, stdout, stderr, peak RSS bytes, CPU seconds) of one
    command, run in a child forked by this worker's server (tests/fork_server.py)."""
    out_path, err_path, peak_path = io_dir / "stdout", io_dir / "stderr", io_dir / "peak"
    peak_path.unlink(missing_ok=True)
    done = SERVER_OF_THIS_PROCESS.run(
        argv, cwd=cwd, env=env, stdout=out_path, stderr=err_path, timeout=timeout, peak=peak_path
    )
    # the child's own figure; polled /proc/PID/status when it was killed before writing it
    rss = int(peak_path.read_text()) * 1024 if peak_path.is_file() else done.polled_rss
    read = lambda p: p.read_bytes().decode("utf-8", "replace")  # noqa: E731
    return done.code, read(out_path), read(err_path), rss, done.cpu_s


def _vm_hwm(pid: int) -> int:
    """Peak RSS in bytes of a running process (0 once it is gone)."""
    try:
        with open(f"/proc/{pid}/status") as fh:
            return int(fh.read().split("VmHWM:")[1].split()[0]) * 1024
    except (OSError, IndexError, ValueError):
        return 0


def _first_error(stderr: str) -> str:
    lines = [ln for ln in stderr.splitlines() if ln.strip()]
    if "Traceback" in stderr and lines:
        return ("traceback: " + lines[-1])[:300]
    errors = [ln for ln in lines if ln.startswith("error:")]
    return (errors or lines or [""])[0][:300]


def _check(case: HostileCase, cmd: Command, as_json: bool, root: Path, store: Path,
           allowed: set[Path]) -> list[str]:  # fmt: skip
    argv = [*cmd.argv, "--json"] if as_json else list(cmd.argv)
    io_dir = root / "_io"
    io_dir.mkdir(exist_ok=True)
    outputs = {p for p in allowed} | ({cmd.output} if cmd.output else set())
    skip = {store, root / "cache", io_dir, *outputs}
    before = _snapshot(root, skip)
    siblings = sorted(os.listdir(root.parent))
    env = {
        **os.environ,
        "DANCEDATA_CACHE": str(root / "cache"),
        "MPLCONFIGDIR": str(root / "cache" / "mpl"),
        "PYTHONPATH": str(REPO),
    }
    started = time.monotonic()
    code, stdout, stderr, rss, cpu = _run(argv, root / "cwd", env, io_dir, case.timeout_s)
    elapsed = time.monotonic() - started
    written = _changed(before, _snapshot(root, skip))
    written += [f"../{n}" for n in sorted(set(os.listdir(root.parent)) - set(siblings))]
    label = f"{case.name}: dancedata {' '.join(a[:60] for a in argv)}"
    problems = []
    if code is None:
        problems.append(f"{label}: no exit after {case.timeout_s:.0f} s (hang)")
    elif code != cmd.expect_exit:
        problems.append(f"{label}: exit {code}, expected {cmd.expect_exit}")
    text = stdout + stderr
    if "Traceback" in text:
        tail = "\n".join(stderr.splitlines()[-4:])
        problems.append(f"{label}: traceback:\n{tail}")
    for name, stream in (("stdout", stdout), ("stderr", stderr)):
        if len(stream) > MAX_OUTPUT_BYTES and not (name == "stdout" and code == 0):
            problems.append(f"{label}: {len(stream)} characters on {name}")
    message = stderr
    if as_json and code is not None:
        try:
            record = json.loads(stdout)
            if not isinstance(record, dict):
                raise ValueError("not an object")
            if code == 1:  # an error record, or a command's own failing summary (validate)
                message = str(record.get("error", stdout))
        except ValueError:
            problems.append(f"{label}: stdout is not one JSON object: {stdout[:200]!r}")
    if cmd.expect and code is not None and not re.search(cmd.expect, message + stdout, re.I):
        problems.append(f"{label}: error does not match /{cmd.expect}/: {_first_error(stderr)!r}")
    if rss > MAX_RSS_BYTES:
        problems.append(f"{label}: peak RSS {rss / 2**20:.0f} MiB > 1 GiB")
    if written:
        problems.append(f"{label}: wrote outside the store/output folder: {written[:8]}")
    if os.environ.get("HOSTILE_RECORD"):
        with open(os.environ["HOSTILE_RECORD"], "a", encoding="utf-8") as fh:
            fh.write(json.dumps({
                "case": case.name, "json": as_json, "argv": cmd.argv[:1], "exit": code,
                "message": _first_error(stderr), "rss_mib": round(rss / 2**20),
                "outside": written[:8], "seconds": round(elapsed, 1), "cpu_s": round(cpu, 2),
                "problems": len(problems),
            }) + "\n")  # fmt: skip
    return problems


def featurized_store_for(request: pytest.FixtureRequest) -> Path:
    """The session's small featurized store (tests/viz_helpers.py), or ``$HOSTILE_STORE``."""
    given = os.environ.get("HOSTILE_STORE")
    if given:
        return Path(given)
    return request.getfixturevalue("small_featurized_store")


def run_case(name: str, featurized_store: Path, tmp_path: Path) -> None:
    """Plant case ``name`` in a fresh copy of ``featurized_store`` and run its commands; fails
    (AssertionError listing every problem) as the module docstring says."""
    case = CASES[name]
    root = tmp_path / "case"
    root.mkdir()
    store = root / "store"
    shutil.copytree(featurized_store, store, symlinks=True)  # a copy: cases edit in place
    for folder in ("work", "cwd", "cache"):
        (root / folder).mkdir()
    commands = case.plant(root / "work", store)
    assert commands, f"{name} names no command"
    problems: list[str] = []
    allowed: set[Path] = set()
    for cmd in commands:
        if cmd.output is not None:
            assert root in cmd.output.parents, f"{name}: output {cmd.output} outside its folder"
        problems += _check(case, cmd, False, root, store, allowed)
        if cmd.json:
            problems += _check(case, cmd, True, root, store, allowed)
        if cmd.output is not None:
            allowed.add(cmd.output)  # a later command may read what an earlier one wrote
    assert not problems, "\n".join(problems)
