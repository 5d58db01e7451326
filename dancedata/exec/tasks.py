"""Run tasks once, durably: finished tasks leave a marker, and a resumed run skips them.

A task is one independent piece of work: plain data with an ``id`` (unique within its
``kind``, and naming exactly the work: a task planned differently gets a different id). Its
function does the work, writes its outputs (zarr chunks that no other task touches, or files
under the build area) and returns a small JSON-able dict. The runner then writes
``.build/units/<kind>/<id>.json`` with that dict — in the worker, after the outputs, atomically
— so a marker always vouches for complete outputs. (The marker folder keeps its old name
``units/``, as dancedata/store/build.py documents the build area.) On the next run with
the same fingerprint, :func:`run_tasks` reads the markers and submits only the tasks without
one.
"""

from __future__ import annotations

import os
import time
from collections.abc import Callable, Iterator, Sequence
from dataclasses import dataclass, field
from functools import partial
from typing import Any, Protocol

from dancedata.exec.executors import Executor
from dancedata.progress import progress_bar, restart_clock
from dancedata.store.build import BuildArea


class Task(Protocol):
    @property
    def id(self) -> str: ...


@dataclass
class TaskReport:
    """What :func:`run_tasks` did: results by ``<kind>/<task id>``, how many tasks there were
    and how many a previous run had already finished (``resumed``)."""

    results: dict[str, dict[str, Any]] = field(default_factory=dict)
    tasks: int = 0
    resumed: int = 0

    def timing(self) -> dict[str, dict[str, float]]:
        """Per kind, the tasks run by this call (resumed ones excluded): how many, their wall
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

    def merge(self, other: TaskReport) -> TaskReport:
        return TaskReport(
            {**self.results, **other.results},
            self.tasks + other.tasks,
            self.resumed + other.resumed,
        )


@dataclass(frozen=True)
class Job:
    """One kind of task: a name (for markers and the progress bar), the task function, and the
    tasks (positional order kept for callers that built ``Job(kind, fn, desc, tasks)``)."""

    kind: str
    fn: Callable[[Any], dict[str, Any]]
    desc: str
    tasks: Sequence[Any]
    task_label: str = "task"


def marker_dir(kind: str) -> str:
    return f"units/{kind}"


def _run_and_mark(build: BuildArea, kind: str, fn: Callable[[Any], Any], task: Any) -> Any:
    """Worker side: do the task, then write its marker (after its outputs)."""
    start = time.perf_counter()
    cpu = time.process_time()
    result = dict(fn(task))
    result["_seconds"] = round(time.perf_counter() - start, 4)
    result["_cpu_seconds"] = round(time.process_time() - cpu, 4)
    result["_pid"] = os.getpid()
    build.write_json(f"{marker_dir(kind)}/{task.id}.json", result)
    return result


def run_tasks(build: BuildArea, jobs: Sequence[Job], executor: Executor) -> TaskReport:
    """Run every task of every job that has no marker yet, all jobs in one submission (so a
    pool never idles between kinds), with one progress bar per job. Returns the results of all
    tasks, finished earlier or now."""
    report = TaskReport()
    for _key in iter_tasks(build, jobs, executor, report):
        pass
    return report


def iter_tasks(
    build: BuildArea, jobs: Sequence[Job], executor: Executor, report: TaskReport
) -> Iterator[str]:
    """:func:`run_tasks` as it goes: fills ``report`` (resumed tasks first) and yields each
    task's ``<kind>/<task id>`` once its result is in ``report.results`` (resumed ones, then
    the others in order of completion), so a caller can use early results while a pool is
    still running later tasks (ingest packs read batch k while the workers read k + 1...)."""
    todo: list[tuple[int, Any]] = []
    bars = []
    for j, job in enumerate(jobs):
        done = build.read_all_json(marker_dir(job.kind))
        ids = [task.id for task in job.tasks]
        if len(set(ids)) != len(ids):
            raise ValueError(f"task ids of {job.kind} are not unique")
        resumed = {i: done[i] for i in ids if i in done}
        report.results.update(
            {f"{job.kind}/{i}": {**r, "_resumed": True} for i, r in resumed.items()}
        )
        report.tasks += len(ids)
        report.resumed += len(resumed)
        todo += [(j, task) for task in job.tasks if task.id not in resumed]
        bar = progress_bar(job.desc, len(ids), job.task_label)
        bar.update(len(resumed))
        bars.append(bar)
    calls = [partial(_run_and_mark, build, jobs[j].kind, jobs[j].fn) for j, _ in todo]
    finished = executor.map_unordered(_apply, list(zip(calls, [t for _, t in todo], strict=True)))
    timed: set[int] = set()
    try:
        for job in jobs:
            for task in job.tasks:
                if f"{job.kind}/{task.id}" in report.results:
                    yield f"{job.kind}/{task.id}"
        for index, result in finished:
            j, task = todo[index]
            key = f"{jobs[j].kind}/{task.id}"
            report.results[key] = result
            if j not in timed:  # the step's time counts from its first task's start
                timed.add(j)
                restart_clock(bars[j], result.get("_seconds", 0.0))
            bars[j].update(1)
            yield key
    finally:
        close = getattr(finished, "close", None)
        if close is not None:  # a caller that stopped early: the pool's pending tasks go
            close()
        for bar in bars:
            bar.close()


def _apply(call: tuple[Callable[[Any], Any], Any]) -> Any:
    fn, task = call
    return fn(task)
