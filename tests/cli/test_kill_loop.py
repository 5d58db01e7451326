"""SIGKILL at random (seeded) moments during ingest, featurize and segment, over and over.

One module-scoped loop does the killing and records what it saw; the tests below judge it:

* at least 20 kills land before the writer commits: "clock" kills at a moment drawn between
  20 ms and the command's uninterrupted duration (measured on a reference store), and "window"
  kills at a moment drawn within the time the reference run held the store lock, counted from
  when this run takes it, so that they fall inside the version build (kills that land after
  the commit are checked too but not counted);
* after every kill the versions that existed before are byte-for-byte intact, ``validate --deep``
  passes, ``store.json`` and ``versions`` show no partial version, and a reader opens the store;
* a kill leaves a stale lock that the next writer takes over and reports; temporary directories
  are invisible meanwhile and gone once a run completes;
* the run that finally completes gives arrays and tables identical, byte for byte, to those of an
  uninterrupted run;
* RESUME (issue 7): each completed featurize/segment manifest records ``counts["units"]`` and
  ``counts["resumed_units"]``, and a featurize that completes after a kill that happened once some
  of its units had finished reports ``resumed_units > 0``.

Set ``DANCEDATA_KILL_SEED`` to replay another sequence of kill moments, and
``DANCEDATA_KILL_REPORT=path.json`` to keep the record of every attempt.
"""

from __future__ import annotations

import json
import os
import random
import re
import shutil
import signal
import sys
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from dancedata.cli.main import _register, app
from typer.testing import CliRunner

import dancedata
from dancedata.ingest.aist import AistIngestOptions, ingest_aist
from dancedata.store.checksums import sha256_file
from dancedata.store.layout import StoreLayout
from dancedata.store.lock import LOCK_FILE
from dancedata.store.reader import _VersionReader
from dancedata.store.validate import validate_store
from dancedata.synth.aist import synth_aist
from tests.fork_server import SERVER_OF_THIS_PROCESS, ForkedProcess
from tests.helpers import REPO

_register()  # the CLI commands, for `versions` run in-process after each kill

pytestmark = pytest.mark.slow

SEED = int(os.environ.get("DANCEDATA_KILL_SEED", "8"))
# Kills per command and plan (see _launch): 23 in total.
KILLS = {
    "ingest": {"clock": 4, "window": 4},
    "featurize": {"clock": 3, "window": 4},
    "segment": {"clock": 4, "window": 4},
}
# Each command runs in a child forked from a server that imported the library
# (tests/fork_server.py): it does its work from the first milliseconds, so kill moments start
# at 20 ms, not after an interpreter start.
MIN_DELAY_S = 0.02
MIN_RANGE_S = 0.05  # the narrowest clock range: a run faster than this still gets kills drawn
_VERSION_DIR = re.compile(r"^v\d+$")
_BAR = re.compile(r"(?P<desc>[a-z][a-z0-9 ]+):\s+\d+%\|[^|]*\|\s*(?P<n>\d+)/(?P<total>\d+)")


def _command(phase: str, raw: Path, store: Path) -> list[str]:
    """The ``dancedata`` arguments of ``phase``."""
    return {
        "ingest": ["ingest", "aist", str(raw), "--store", str(store)],
        "featurize": ["featurize", str(store)],
        "segment": ["segment", str(store)],
    }[phase]


def _version_files(vdir: Path) -> dict[str, str]:
    return {
        p.relative_to(vdir).as_posix(): sha256_file(p)
        for p in sorted(vdir.rglob("*"))
        if p.is_file()
    }


def _snapshot(store: Path) -> dict[str, dict[str, str]]:
    layout = StoreLayout(store)
    return {name: _version_files(layout.version_dir(name)) for name in layout.committed_versions()}


def _finished_units(log_text: str) -> dict[str, int]:
    """Highest completed count each progress bar showed before the process died."""
    done: dict[str, int] = {}
    for match in _BAR.finditer(log_text.replace("\r", "\n")):
        desc = match.group("desc").strip()
        done[desc] = max(done.get(desc, 0), int(match.group("n")))
    return done


def _version_data(store: Path, version: str) -> dict[str, Any]:
    """Every array (raw chunk bytes and decoded values) and table of one version."""
    reader = _VersionReader(store, version)
    out: dict[str, Any] = {}
    zarr_dir = reader.path / "data.zarr"
    for name in reader.array_names():
        chunks = (
            sorted((zarr_dir / name / "c").rglob("*")) if (zarr_dir / name / "c").exists() else []
        )
        out[f"chunks:{name}"] = {
            c.relative_to(zarr_dir).as_posix(): c.read_bytes() for c in chunks if c.is_file()
        }
        array = reader.array(name)
        out[f"array:{name}"] = (str(array.dtype), np.asarray(array[...]))
    for table in ("sequences", "music", "measures", "splits"):
        if reader.has_table(table):
            out[f"table:{table}"] = reader.table(table)
    return out


def _differences(a: dict[str, Any], b: dict[str, Any]) -> list[str]:
    problems = [f"{k}: only on one side" for k in sorted(set(a) ^ set(b))]
    for key in sorted(set(a) & set(b)):
        left, right = a[key], b[key]
        if key.startswith("array:"):
            same = left[0] == right[0] and np.array_equal(left[1], right[1], equal_nan=True)
        elif key.startswith("table:"):
            same = left.equals(right)
        else:
            same = left == right
        if not same:
            problems.append(f"{key}: differs")
    return problems


@dataclass
class KillLoop:
    """What the loop did and saw."""

    attempts: list[dict[str, Any]] = field(default_factory=list)
    violations: list[str] = field(default_factory=list)
    completions: list[dict[str, Any]] = field(default_factory=list)
    durations: dict[str, float] = field(default_factory=dict)
    lock_windows: dict[str, float] = field(default_factory=dict)
    elapsed_s: float = 0.0

    def kills(self, phase: str | None = None, plan: str | None = None) -> int:
        return sum(
            a["outcome"] == "killed"
            and (phase is None or a["phase"] == phase)
            and (plan is None or a["plan"] == plan)
            for a in self.attempts
        )


def _check_after_kill(store: Path, before: dict[str, dict[str, str]], label: str) -> list[str]:
    """Invariants that must hold whenever a writer has just died."""
    problems: list[str] = []
    layout = StoreLayout(store)
    committed = layout.committed_versions()
    for name, files in before.items():
        if name not in committed:
            problems.append(f"{label}: version {name} disappeared")
        elif _version_files(layout.version_dir(name)) != files:
            problems.append(f"{label}: version {name} changed on disk")
    for entry in layout.versions_dir.iterdir():
        if not (entry.name.startswith(".tmp-") or entry.name in committed):
            problems.append(f"{label}: visible entry {entry.name} is not a committed version")
    pointer = layout.read_pointer().get("latest")
    if pointer is not None and pointer not in committed:
        problems.append(f"{label}: store.json names {pointer}, which is not committed")
    if layout.latest() != committed[-1]:
        problems.append(f"{label}: latest {layout.latest()} is not the newest committed version")
    problems += [f"{label}: validate --deep: {p}" for p in validate_store(store, deep=True)]
    # What `dancedata versions` shows: exactly the committed versions, the newest as latest,
    # and a note for each unfinished temporary version.
    shown = CliRunner().invoke(app, ["versions", str(store), "--json"])
    rows = json.loads(shown.stdout)
    if [r["version"] for r in rows] != committed or not rows[-1]["latest"]:
        problems.append(f"{label}: `versions` shows {rows}")
    for tmp in layout.temp_dirs():
        if f"unfinished temporary version {tmp.name}" not in shown.stderr:
            problems.append(f"{label}: `versions` does not report {tmp.name}")
    opened = dancedata.open_store(str(store))
    for name in opened.array_names():
        np.asarray(opened.zarr(name)[...])  # every visible chunk decodes
    return problems


def _lock_token(store: Path) -> str | None:
    try:
        return json.loads((store / LOCK_FILE).read_text(encoding="utf-8")).get("token")
    except (OSError, ValueError):
        return None


def _launch(
    cmd: list[str],
    store: Path,
    log: Path,
    plan: str,
    rng: random.Random,
    loop: KillLoop,
    phase: str,
    learn: bool = True,
) -> tuple[ForkedProcess, str | None, float | None]:
    """Run ``dancedata CMD`` in a process of its own (forked from this worker's server, which
    imported the library once, so the kill ranges are the command's work, not the interpreter
    start); kill its process group according to ``plan``:

    * ``clock``: at a moment drawn from [20 ms, uninterrupted duration] after the start;
    * ``window``: at a moment drawn from [0, lock-held duration] after it takes the store lock,
      so the kill lands inside the version build;
    * ``final``: never.

    Returns the finished process, a description of the kill (None if not killed) and the time
    the process took the lock (None if it was not seen taking it). With ``learn``, a run that
    completes narrows both ranges to its own timings (see :func:`_learn_durations`).
    """
    stale = _lock_token(store)
    started = time.monotonic()
    locked_at: float | None = None
    proc = SERVER_OF_THIS_PROCESS.spawn(
        cmd, cwd=REPO, env=dict(os.environ), stdout=Path(os.devnull), stderr=log
    )
    kill_at: float | None = None
    what = None
    if plan == "clock":
        delay = rng.uniform(MIN_DELAY_S, loop.durations[phase])
        kill_at, what = started + delay, f"{delay:.2f} s after start"
    while proc.poll() is None:
        now = time.monotonic()
        if locked_at is None and _lock_token(store) not in (None, stale):
            locked_at = now - started
            if plan == "window":
                delay = rng.uniform(0.0, loop.lock_windows[phase])
                kill_at = now + delay
                what = f"{delay:.2f} s after taking the lock at {locked_at:.2f} s"
        if kill_at is not None and now >= kill_at:
            os.killpg(proc.pid, signal.SIGKILL)
            proc.wait()
            return proc, what, locked_at
        time.sleep(0.005)
    if learn:
        _learn_durations(loop, phase, time.monotonic() - started, locked_at)
    return proc, None, locked_at


def _learn_durations(loop: KillLoop, phase: str, seconds: float, locked_at: float | None) -> None:
    """Shrink the kill ranges to the fastest uninterrupted run seen: the first run of a command
    is often slower (cold caches, JIT), and delays past the end of a run kill nothing."""
    fastest = min(loop.durations.get(phase, seconds), seconds)
    loop.durations[phase] = max(fastest, MIN_DELAY_S + MIN_RANGE_S)
    if locked_at is not None:
        window = max(seconds - locked_at, 0.05)
        loop.lock_windows[phase] = min(loop.lock_windows.get(phase, window), window)


def _build_state(store: Path) -> dict[str, Any]:
    """For the record: what each temporary version holds of resume state (issue 7's .build/)."""
    state: dict[str, Any] = {}
    for tmp in StoreLayout(store).temp_dirs():
        build = tmp / ".build"
        state[tmp.name] = {
            "prepared": (build / "prepared.json").is_file(),
            "unit_markers": sorted(
                p.relative_to(build / "units").as_posix() for p in (build / "units").rglob("*.json")
            )
            if (build / "units").is_dir()
            else [],
            "entries": sorted(p.name for p in tmp.iterdir()),
        }
    return state


def _kill_phase(
    loop: KillLoop,
    phase: str,
    raw: Path,
    store: Path,
    work: Path,
    rng: random.Random,
    reference: dict[str, Any],
) -> None:
    """Kill ``phase`` runs until KILLS[phase] kills of each plan landed, then let one complete.
    A run that finishes before its kill commits; the store is then reset to the phase start."""
    base = work / f"base-{phase}"
    shutil.copytree(store, base, symlinks=True)  # copytree does not keep hard links: fine here
    cmd = _command(phase, raw, store)
    chain_evidence: dict[str, int] = {}
    attempt = 0
    while True:
        attempt += 1
        missing = {plan: wanted - loop.kills(phase, plan) for plan, wanted in KILLS[phase].items()}
        if all(n <= 0 for n in missing.values()):
            plan = "final"
        elif missing["window"] > 0 and (attempt % 2 or missing["clock"] <= 0):
            plan = "window"
        else:
            plan = "clock"
        before = _snapshot(store)
        lock_before = _lock_token(store)
        temps_before = [p.name for p in StoreLayout(store).temp_dirs()]
        build_before = _build_state(store)
        log = work / f"{phase}-{attempt}.log"
        # Only a run starting from scratch (nothing to resume) sets the kill ranges.
        proc, kill, locked_at = _launch(
            cmd, store, log, plan, rng, loop, phase, learn=not temps_before
        )
        killed = kill is not None
        text = log.read_text(errors="replace")
        label = f"{phase} attempt {attempt}" + (f" (killed {kill})" if killed else "")
        lock_after = _lock_token(store)
        record = {
            "phase": phase,
            "attempt": attempt,
            "plan": plan,
            "kill": kill,
            "outcome": "killed" if killed else "completed",
            "returncode": proc.returncode,
            "locked_at_s": locked_at,
            "lock_left": lock_after is not None,
            "temps_left": [p.name for p in StoreLayout(store).temp_dirs()],
            "build_state": _build_state(store),
            "units_done": _finished_units(text),
        }
        loop.attempts.append(record)
        # A run that found a stale lock and got past it must say it took it over.
        took_over = lock_before is not None and lock_after != lock_before
        if took_over and "took over a stale store lock" not in text:
            loop.violations.append(f"{label}: took over a stale lock without reporting it")
        if not killed and proc.returncode != 0:
            loop.violations.append(f"{label}: exited {proc.returncode}: {text[-800:]}")
            return
        if killed:
            loop.violations += _check_after_kill(store, before, label)
        layout = StoreLayout(store)
        new = [v for v in layout.committed_versions() if v not in before]
        if not new:
            # Units this killed run finished are what the next run of the chain may resume.
            for desc, n in record["units_done"].items():
                chain_evidence[desc] = max(chain_evidence.get(desc, 0), n)
            if plan == "final":
                loop.violations.append(f"{label}: the uninterrupted run committed nothing")
                return
            continue
        # Committed: a finished run, or a kill that landed after the commit rename (which is
        # checked like any kill but not counted as one: nothing was left half-done).
        record["committed"] = new[-1]
        if killed:
            record["outcome"] = "killed_after_commit"
        if layout.temp_dirs() and not killed:
            loop.violations.append(f"{label}: temporary dirs left after a completed run")
        diff = _differences(_version_data(store, new[-1]), reference[phase])
        loop.violations += [f"{label}: {new[-1]} vs uninterrupted run: {d}" for d in diff]
        loop.completions.append(
            {
                "phase": phase,
                "label": label,
                "temps_before": temps_before,
                "build_state_before": build_before,
                "evidence": dict(chain_evidence),
                "counts": layout.read_manifest(new[-1]).get("counts", {}),
            }
        )
        chain_evidence = {}
        if plan == "final":
            return
        shutil.rmtree(store)
        shutil.copytree(base, store, symlinks=True)


@pytest.fixture(scope="module")
def kill_loop(tmp_path_factory) -> KillLoop:
    work = tmp_path_factory.mktemp("killloop")
    raw, ref, store = work / "raw", work / "ref", work / "store"
    synth_aist(raw, n_sequences=3, seed=SEED)
    loop = KillLoop()
    rng = random.Random(SEED)
    start = time.monotonic()
    reference: dict[str, Any] = {}
    for phase in ("ingest", "featurize", "segment"):
        log = work / f"ref-{phase}.log"
        proc, _, locked_at = _launch(_command(phase, raw, ref), ref, log, "final", rng, loop, phase)
        assert proc.returncode == 0 and locked_at is not None, log.read_text()
        reference[phase] = _version_data(ref, StoreLayout(ref).latest())
    # The work store starts with one version (a one-genre ingest) that every kill must spare.
    genre = sorted(p.name[:3] for p in (raw / "motions").glob("*.pkl"))[0]
    ingest_aist(store, raw, AistIngestOptions(genres=[genre]))
    for phase in ("ingest", "featurize", "segment"):
        _kill_phase(loop, phase, raw, store, work, rng, reference)
    loop.elapsed_s = time.monotonic() - start
    summary = {p: {plan: loop.kills(p, plan) for plan in KILLS[p]} for p in KILLS}
    print(f"\nkill loop: seed {SEED}, kills {summary}, {loop.elapsed_s:.0f} s", file=sys.stderr)
    report = Path(os.environ.get("DANCEDATA_KILL_REPORT", work / "kill_loop.json"))
    report.write_text(
        json.dumps(
            {
                "durations": loop.durations,
                "lock_windows": loop.lock_windows,
                "attempts": loop.attempts,
                "violations": loop.violations,
                "completions": loop.completions,
            },
            indent=1,
            default=str,
        )
    )
    return loop


def test_at_least_twenty_kills_landed_in_all_three_commands(kill_loop):
    assert kill_loop.kills() >= 20, kill_loop.attempts
    for phase, plans in KILLS.items():
        for plan, wanted in plans.items():
            assert kill_loop.kills(phase, plan) >= wanted, (phase, plan)
    # Window kills land while the writer holds the lock, i.e. inside the version build.
    for phase in KILLS:
        inside = [
            a
            for a in kill_loop.attempts
            if a["phase"] == phase and a["plan"] == "window" and a["outcome"] == "killed"
        ]
        assert all(a["locked_at_s"] is not None for a in inside)


def test_every_kill_left_the_store_intact_valid_and_without_partial_versions(kill_loop):
    assert kill_loop.violations == []


def test_each_command_finally_completes_identical_to_an_uninterrupted_run(kill_loop):
    # (The comparison itself is among the violations; here: every phase did complete.)
    assert {c["phase"] for c in kill_loop.completions} == set(KILLS)
    assert not [v for v in kill_loop.violations if "uninterrupted" in v]


def test_kills_left_stale_locks_and_temporary_dirs_that_later_runs_handled(kill_loop):
    killed = [a for a in kill_loop.attempts if a["outcome"] == "killed"]
    assert any(a["lock_left"] for a in killed), "no kill ever landed while the lock was held"
    assert any(a["temps_left"] for a in killed), "no kill ever left a temporary version"
    completed = [a for a in kill_loop.attempts if a["outcome"] == "completed"]
    assert all(not a["temps_left"] and not a["lock_left"] for a in completed), completed


# -- RESUME: needs the issue-7 work (featurize/segment record units and resumed_units) ---------
_UNIT_BARS = ("featurize motion", "featurize audio")


def test_resume_counts_are_recorded_and_used_after_a_late_kill(kill_loop):
    """NEEDS ISSUE 7 (resume): fails until featurize/segment record counts["units"] and
    counts["resumed_units"] and a run after a kill skips the units already finished."""
    resumable = [c for c in kill_loop.completions if c["phase"] in ("featurize", "segment")]
    assert resumable
    for done in resumable:
        counts = done["counts"]
        assert "units" in counts and "resumed_units" in counts, (done["label"], counts)
        assert 0 <= counts["resumed_units"] <= counts["units"], (done["label"], counts)
    late = [
        c
        for c in resumable
        if c["phase"] == "featurize" and any(c["evidence"].get(bar, 0) > 0 for bar in _UNIT_BARS)
    ]
    for done in late:
        # On failure the message shows what the killed run left: unit markers present means the
        # resume skipped them; none although progress showed finished units means the markers
        # were lost (e.g. removed at the start of commit, before the rename).
        assert done["counts"]["resumed_units"] > 0, (
            done["label"],
            done["evidence"],
            done["build_state_before"],
        )
