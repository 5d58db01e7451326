"""Hostile stores, configs and model outputs: the case interface of the untrusted-input corpus.

A case plants one hostile thing (a nested ``store.json``, a symlinked version, a sparse ``.npy``,
an experiment config whose id is a path, ...) into a fresh copy of a small featurized store and
names the ``dancedata`` commands that must refuse it. The runner (``tests/hostile_runner.py``,
called by ``tests/cli/test_hostile_inputs.py`` and ``tests/cli/test_hostile_inputs_files.py``) runs
every command, plain and with ``--json`` where the command has it, and fails on a traceback,
an exit code other than 0 or 1, a hang (timeout), a file written outside the store or output
folder, or a process whose peak RSS is above 1 GB.

Case modules (``hostile_*.py`` beside this file) add cases with :func:`hostile_case`; each case is
named by its class, the classes of the untrusted-input issue: ``store-metadata``, ``arrays``,
``links``, ``values``, ``names``, ``configs``, ``generated``, ``paths``, ``pose-files``.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path

CLASSES = (
    "store-metadata",
    "arrays",
    "links",
    "values",
    "names",
    "configs",
    "generated",
    "paths",
    "pose-files",
)


@dataclass(frozen=True)
class Command:
    """One command to run against a planted case.

    ``argv`` follows ``dancedata``; ``expect_exit`` is 1 for a refusal (0 when the command must
    succeed despite the case, e.g. ``validate`` printing problems is still 1). ``output`` is a
    folder the command may write into (besides the store); anything else written is a failure.
    ``json`` runs it a second time with ``--json`` and requires one JSON object on stdout.
    ``expect`` is a regular expression the one-line error must match (searched in stderr, or in
    the JSON object's ``error`` under ``--json``)."""

    argv: list[str]
    expect_exit: int = 1
    expect: str = ""
    json: bool = False
    output: Path | None = None


@dataclass(frozen=True)
class HostileCase:
    """A planted hostile input: ``plant(work, store)`` edits the copy of the store at ``store``
    (or writes files under ``work``) and returns the commands that must refuse it."""

    name: str
    klass: str
    plant: Callable[[Path, Path], list[Command]]
    note: str = ""
    timeout_s: float = 60.0
    tags: tuple[str, ...] = field(default_factory=tuple)


CASES: dict[str, HostileCase] = {}


def hostile_case(
    klass: str, *, note: str = "", timeout_s: float = 60.0
) -> Callable[[Callable[[Path, Path], list[Command]]], Callable[[Path, Path], list[Command]]]:
    """Register ``plant`` as the case ``<klass>/<function name>``."""
    if klass not in CLASSES:
        raise ValueError(f"unknown case class {klass!r}; known: {', '.join(CLASSES)}")

    def register(plant: Callable[[Path, Path], list[Command]]):
        name = f"{klass}/{plant.__name__}"
        if name in CASES:
            raise ValueError(f"duplicate hostile case {name}")
        CASES[name] = HostileCase(
            name=name, klass=klass, plant=plant, note=note, timeout_s=timeout_s
        )
        return plant

    return register


def all_cases() -> dict[str, HostileCase]:
    """Every case of every ``hostile_*.py`` module beside this file."""
    import importlib

    for module in sorted(Path(__file__).parent.glob("hostile_*.py")):
        importlib.import_module(f"tests.data.bad.{module.stem}")
    return dict(CASES)
