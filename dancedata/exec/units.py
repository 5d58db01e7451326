"""Run work units once, durably: finished units leave a marker, and a resumed run skips them.

A unit is plain data with an ``id`` (unique within its ``kind``, and naming exactly the work:
a unit planned differently gets a different id). Its function does the work, writes its
outputs (zarr chunks that no other unit touches, or files under the build area) and returns a
small JSON-able dict. The runner then writes ``.build/units/<kind>/<id>.json`` with that dict —
in the worker, after the outputs, atomically — so a marker always vouches for complete outputs.
On the next run with the same fingerprint, :func:`run_units` reads the markers and submits only
the units without one.
"""

from __future__ import annotations

import os
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from functools import partial
from typing import Any, Protocol

from dancedata.exec.executors import Executor
from dancedata.progress import progress_bar
from dancedata.store.build import BuildArea


class Unit(Protocol):
    @property
    def id(self) -> str: ...


@dataclass
class UnitReport:
    """What :func:`run_units` did: results by unit id, and how many units it could skip."""

    results: dict[str, dict[str, Any]] = field(default_factory=dict)
    units: int = 0
    resumed: int = 0

    def timing(self) -> dict[str, dict[str, float]]:
        """Per kind, the units run by this call (resumed ones excluded): how many, their wall
        seconds summed over workers, and their CPU seconds."""
        out: dict[str, dict[str, float]] = {}
        for key, result in self.results.items():
            if "_seconds" not in result or result.get("_resumed"):
                continue
            kind = key.split("/", 1)[0]
            entry = out.setdefault(kind, {"run": 0, "seconds": 0.0, "cpu_seconds": 0.0})
            entry["run"] += 1
            entry["seconds"] = round(entry["seconds"] + result["_seconds"], 3)
            entry["cpu_seconds"] = round(entry["cpu_seconds"] + result["_cpu_seconds"], 3)
        return out

    def merge(self, other: UnitReport) -> UnitReport:
        return UnitReport(
            {**self.results, **other.results},
            self.units + other.units,
            self.resumed + other.resumed,
        )


@dataclass(frozen=True)
class Job:
    """One kind of unit: a name (for markers and the progress bar) and the unit function."""

    kind: str
    fn: Callable[[Any], dict[str, Any]]
    desc: str
    units: Sequence[Any]
    unit_label: str = "unit"


def marker_dir(kind: str) -> str:
    return f"units/{kind}"


def _run_and_mark(build: BuildArea, kind: str, fn: Callable[[Any], Any], unit: Any) -> Any:
    """Worker side: do the unit, then write its marker (after its outputs)."""
    start = time.perf_counter()
    cpu = time.process_time()
    result = dict(fn(unit))
    result["_seconds"] = round(time.perf_counter() - start, 4)
    result["_cpu_seconds"] = round(time.process_time() - cpu, 4)
    result["_pid"] = os.getpid()
    build.write_json(f"{marker_dir(kind)}/{unit.id}.json", result)
    return result


def run_units(build: BuildArea, jobs: Sequence[Job], executor: Executor) -> UnitReport:
    """Run every unit of every job that has no marker yet, all jobs in one submission (so a
    pool never idles between kinds), with one progress bar per job. Returns the results of all
    units, finished earlier or now."""
    report = UnitReport()
    todo: list[tuple[int, Any]] = []
    bars = []
    for j, job in enumerate(jobs):
        done = build.read_all_json(marker_dir(job.kind))
        ids = [unit.id for unit in job.units]
        if len(set(ids)) != len(ids):
            raise ValueError(f"unit ids of {job.kind} are not unique")
        resumed = {i: done[i] for i in ids if i in done}
        report.results.update(
            {f"{job.kind}/{i}": {**r, "_resumed": True} for i, r in resumed.items()}
        )
        report.units += len(ids)
        report.resumed += len(resumed)
        todo += [(j, unit) for unit in job.units if unit.id not in resumed]
        bar = progress_bar(job.desc, len(ids), job.unit_label)
        bar.update(len(resumed))
        bars.append(bar)
    tasks = [partial(_run_and_mark, build, jobs[j].kind, jobs[j].fn) for j, _ in todo]
    try:
        for index, result in executor.map_unordered(
            _apply, list(zip(tasks, [u for _, u in todo], strict=True))
        ):
            j, unit = todo[index]
            report.results[f"{jobs[j].kind}/{unit.id}"] = result
            bars[j].update(1)
    finally:
        for bar in bars:
            bar.close()
    return report


def _apply(task: tuple[Callable[[Any], Any], Any]) -> Any:
    fn, unit = task
    return fn(unit)
