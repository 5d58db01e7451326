"""Polish a researcher notices (issue 23, item 7): progress timed per step and silent after an
error, the command list in pipeline order, usage lines without placeholders."""

from __future__ import annotations

import io
import re
import time
from dataclasses import dataclass

import pytest

from dancedata.exec.executors import SerialExecutor
from dancedata.exec.tasks import Job, run_tasks
from dancedata.progress import PlainProgress
from dancedata.store.build import BuildArea


def test_no_progress_line_after_an_error() -> None:
    ok, failed = io.StringIO(), io.StringIO()
    bar = PlainProgress("checksums", 3, "file", interval_s=60, stream=ok)
    bar.update(3)
    bar.close()
    assert ok.getvalue() == "checksums: 3/3 file (100%, 0.0 s)\n"
    bar = PlainProgress("checksums", 3, "file", interval_s=60, stream=failed)
    with pytest.raises(ValueError):
        try:
            raise ValueError("bad file")
        finally:
            bar.close()
    assert failed.getvalue() == ""


@dataclass(frozen=True)
class _Task:
    id: str


def _slow(task: _Task) -> dict:
    time.sleep(0.4)
    return {"task": task.id}


def _fast(task: _Task) -> dict:
    return {"task": task.id}


def test_each_step_is_timed_from_its_own_start(tmp_path, monkeypatch) -> None:
    """All jobs' bars are made up front; the second step's time starts with its first task,
    not with the first step (it was 0.8 s here before)."""
    lines: list[str] = []
    monkeypatch.setattr(PlainProgress, "_write", lambda self: lines.append(self.line()))
    monkeypatch.setattr("dancedata.progress._stderr_is_terminal", lambda: False)
    tasks = [_Task("a"), _Task("b")]
    jobs = [Job("slow", _slow, "step one", tasks), Job("fast", _fast, "step two", tasks)]
    run_tasks(BuildArea(str(tmp_path)), jobs, SerialExecutor())
    times = {line.split(":")[0]: float(re.search(r"([\d.]+) s\)$", line)[1]) for line in lines}
    assert times["step one"] >= 0.8 and times["step two"] < 0.3, lines
