"""What an ingest source is: the contract between a source module and the ingest engine.

A *source* (AIST++, BVH, video poses, ...) knows one input format: which files make up a
dataset, how to read one sequence from them, and what its arrays and extra table columns mean.
Everything else — checksums and the fingerprint, the store lock, ``--on-error``, parallel and
resumable reads, frame offsets, the ``sequences`` row, table writing and the commit — is the
engine's (:func:`dancedata.ingest.engine.ingest`).

How a source plugs in (see :class:`Source`): a folder ``dancedata/ingest/<name>/`` whose
``source.py`` holds a :class:`Source` subclass decorated ``@register_source("<name>")``
(:mod:`dancedata.ingest.registry`; its constructor takes the inputs and an options object and
sets ``command``, "ingest <name>") and whose ``__init__.py`` holds the command-line ``Options``
(:mod:`dancedata.ingest.options`: ``dancedata ingest <name>`` is built from it). The contract
is three methods:

1. ``plan(store, checksums, skips)`` → :class:`IngestPlan`: one :class:`ReadTask` per sequence
   (picklable items), a top-level ``parse`` function that turns one item into whatever the
   source parsed (run in worker processes, may raise :class:`~dancedata.errors.DancedataError`),
   the fingerprint lines, the manifest's input list (``checksums`` hashes files once) and the
   stored arrays it declares (:class:`StoredArray`, or a function of the first record). A store
   the source cannot write is refused here (raise InputError).
2. ``read(task, parsed)`` → :class:`SequenceRecord`: one sequence's columns and arrays, one row
   per frame, from ``parsed()`` (the parse result; raises the parse's error). Raise
   DancedataError to refuse it: the engine skips or fails by ``--on-error``.
3. ``finish(records, totals)`` → :class:`Finished`: the music table, the other tables, the
   manifest counts and the group attrs.

Optional, for work under the store lock: ``under_lock`` (store state the fingerprint depends
on, e.g. ``--append``), ``prepare`` (input work done only when there is something to ingest,
e.g. music headers; may drop tasks) and ``open`` (copy a parent's frames, keep its rows).
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from dancedata.errors import DancedataError, InputError
from dancedata.store.checksums import describe_input

if TYPE_CHECKING:
    from dancedata.store.command_result import CommandResult
    from dancedata.store.writer import VersionWriter

__all__ = [
    "ON_ERROR_CHOICES",
    "Finished",
    "FrameArrayTarget",
    "IngestPlan",
    "IngestTotals",
    "InputChecksums",
    "MusicTable",
    "ReadTask",
    "SequenceRecord",
    "SettingsConflict",
    "SkipPolicy",
    "Source",
    "StoredArray",
]

ON_ERROR_CHOICES = ("fail", "skip")


# ----------------------------------------------------------------------------- inputs


class SettingsConflict(InputError):
    """An input that contradicts the ones accepted before it under the run's settings (ingest
    video: a video at another frame rate than the first, without ``--fps``). The settings are
    at fault rather than the input, so ``--on-error skip`` does not skip it: the run fails."""


class SkipPolicy:
    """``--on-error``: "fail" re-raises the first bad input; "skip" records it (file and
    problem) for the manifest's ``skipped`` list and goes on. A :class:`SettingsConflict` is
    always re-raised."""

    def __init__(self, on_error: str) -> None:
        if on_error not in ON_ERROR_CHOICES:
            raise InputError(f"on_error must be 'fail' or 'skip', not {on_error!r}")
        self.on_error = on_error
        self.skipped: list[dict[str, str]] = []

    def fail_or_skip(self, exc: DancedataError, path: Path | str | None) -> None:
        if self.on_error != "skip" or isinstance(exc, SettingsConflict):
            raise exc
        self.skipped.append({"path": str(exc.path or path or ""), "error": exc.problem})


class InputChecksums:
    """Input files described (path, bytes, sha256) once per run, in first-asked order: the
    manifest's ``inputs`` list."""

    def __init__(self) -> None:
        self.described: dict[str, dict[str, Any]] = {}

    def sha(self, path: Path) -> str:
        """sha256 of an input file; InputError when it is not a file."""
        key = str(path)
        if key not in self.described:
            if not path.is_file():
                raise InputError("no such file", path)
            self.described[key] = describe_input(path)
        return self.described[key]["sha256"]

    def inputs(self) -> list[dict[str, Any]]:
        return list(self.described.values())


# ----------------------------------------------------------------------------- plan


@dataclass(frozen=True)
class ReadTask:
    """One sequence to read: ``item`` goes to the plan's ``parse`` function (in a worker, so it
    must pickle: paths as strings, settings as frozen dataclasses); ``path`` names the input
    in a skip record when the parse or ``read`` fails without naming a file."""

    path: str
    item: Any


@dataclass
class IngestPlan:
    """What a source plans before anything is written.

    Attributes:
        config: every setting that changes the data (fingerprinted, in the manifest).
        fingerprint_keys: one line per input binding it to its checksum, in input order.
        inputs: the manifest's input list (dicts with path, bytes, sha256); None: every file
            described through the engine's InputChecksums by the time the version opens.
        tasks: one per sequence, in store order.
        parse: top-level function ``item -> value`` (values: dataclasses, numpy arrays and JSON
            scalars, saved between runs without pickle).
        arrays: the frame arrays every record carries, or a function declaring them from the
            first record read (a skeleton's joint count).
        task_kind: the resumable reads' name (build-area folder) and ``read_desc`` their
            progress label; ``batch_size``: tasks per resumable read batch (None: the
            engine's default).
        workers: processes reading (``dask``: a scheduler address instead). Not fingerprinted.
        create_store: take the lock creating the store when missing (False for ``--append``).
        fingerprint_before_lock: the fingerprint needs no store state (no ``under_lock``
            lines), so the engine may look for a committed version carrying it before waiting
            for the lock.
        resumable: keep finished read batches across a killed run.
        empty_error: raised when every sequence was skipped.
        sequences_desc: progress label of the in-order packing.
    """

    config: dict[str, Any]
    fingerprint_keys: list[str]
    inputs: list[dict[str, Any]] | None
    tasks: list[ReadTask]
    parse: Callable[[Any], Any]
    task_kind: str
    arrays: Sequence[StoredArray] | Callable[[SequenceRecord], Sequence[StoredArray]] = ()
    read_desc: str = "read inputs"
    sequences_desc: str = "ingest sequences"
    sequences_unit: str = "seq"
    batch_size: int | None = None
    workers: int = 1
    dask: str | None = None
    wait_for_lock: bool = False
    create_store: bool = True
    fingerprint_before_lock: bool = True
    resumable: bool = True
    empty_error: InputError = field(
        default_factory=lambda: InputError("every input was skipped; nothing to ingest")
    )


# ----------------------------------------------------------------------------- records


@dataclass(frozen=True)
class StoredArray:
    """One frame-concatenated array of the version: ``motion/<name>`` with rows of
    ``row_shape`` (one row per frame), stored as ``dtype``."""

    name: str
    row_shape: tuple[int, ...]
    dtype: Any
    attrs: dict[str, Any] = field(default_factory=dict)
    compressors: Any = "auto"
    chunks_per_write: int = 1
    group: str = "motion"


@dataclass
class SequenceRecord:
    """One accepted sequence: its table columns and its arrays.

    The engine builds the ``sequences`` row from these fields (see
    :func:`dancedata.ingest.engine.sequence_row`): contract columns, then ``name_columns``
    (extra naming columns, e.g. AIST++'s camera), the audio coverage columns, then
    ``bpm_estimated`` when the source records it (not None), then ``columns``.

    Attributes:
        seq_id, source: the sequence id and the source's name in the table.
        path, sha256: the input file the row names, and its checksum.
        fps, n_frames: frame rate (frames/s) and frame count of the stored arrays.
        arrays: name → (n_frames, *row_shape) rows, one entry per declared StoredArray.
        music_key: the source's key of this sequence's music in ``music_table`` (None: none).
        music_id: the music id when the music table holds no row for it (AIST++ keeps the id
            of missing music); a music row's id wins.
        bpm: the sequence's tempo, beats per minute; None: the music row's.
        bpm_estimated: whether a music-row tempo was estimated; None: no such column.
        item: anything the source keeps for its tables and counts (not stored).
    """

    seq_id: str
    source: str
    path: str
    sha256: str
    fps: float
    n_frames: int
    arrays: dict[str, np.ndarray]
    genre: str | None = None
    situation: str | None = None
    dancer: str | None = None
    choreo: str | None = None
    music_key: str | None = None
    music_id: str | None = None
    bpm: float | None = None
    bpm_estimated: bool | None = None
    name_columns: dict[str, Any] = field(default_factory=dict)
    columns: dict[str, Any] = field(default_factory=dict)
    item: Any = None
    frame_start: int = -1  # set by the engine when the arrays are appended


@dataclass
class MusicTable:
    """The version's music table rows (frame ranges packed from 0, feature frames at the
    motion rate) and, per music key of the records, its row; ``write_empty``: write the table
    even when it has no rows (AIST++ stores always have one)."""

    rows: list[dict[str, Any]] = field(default_factory=list)
    by_key: dict[str, dict[str, Any]] = field(default_factory=dict)
    write_empty: bool = False


@dataclass(frozen=True)
class IngestTotals:
    """What the engine counted, for the source's manifest counts."""

    frames: int  # every frame in the version's arrays (kept ones too)
    new_frames: int
    sequences: int  # rows of the sequences table (kept ones too)
    skipped: int
    read_counts: dict[str, int]  # {"units": read batches, "resumed_units": finished earlier}

    def counts(self, music: MusicTable) -> dict[str, Any]:
        """The manifest counts every source starts from."""
        return {
            "sequences": self.sequences,
            "frames": self.frames,
            "music": len(music.rows),
            "skipped": self.skipped,
            **self.read_counts,
        }


@dataclass
class Finished:
    """What a source adds once every record is read: the music table, the tables besides
    sequences and music (splits, cameras; by name, in write order), the manifest counts and the
    group attrs written on the arrays' groups ({"motion": {...}})."""

    music: MusicTable
    counts: dict[str, Any]
    tables: dict[str, list[dict[str, Any]]] = field(default_factory=dict)
    attrs: dict[str, dict[str, Any]] = field(default_factory=dict)


class FrameArrayTarget:
    """Where a source may append rows itself before the records (``--append`` copying its
    parent's frames): implemented by the engine's frame arrays."""

    frames: int

    def declare(self, specs: Sequence[StoredArray]) -> None:
        raise NotImplementedError

    def append(self, arrays: dict[str, np.ndarray]) -> None:
        raise NotImplementedError


# ----------------------------------------------------------------------------- the source


class Source:
    """Base class of an ingest source (see the module docstring for how one plugs in).

    Required: ``name`` (set by :func:`~dancedata.ingest.registry.register_source`),
    ``command``, ``on_error``, :meth:`plan`, :meth:`read`, :meth:`finish`.
    """

    name: str = ""
    command: str = ""
    on_error: str = "fail"
    # The version this one is based on (``--append``: its parent), set by under_lock.
    based_on: str | None = None

    def plan(self, store: str | Path, checksums: InputChecksums, skips: SkipPolicy) -> IngestPlan:
        """List the inputs, tasks and arrays; refuse a store this source cannot write (raise
        InputError). Bad inputs found here go through ``skips``."""
        raise NotImplementedError

    def read(self, task: ReadTask, parsed: Callable[[], Any]) -> SequenceRecord:
        """One sequence as a record, checked against the store (frame rate, skeleton, music):
        ``parsed()`` is the plan's ``parse`` of ``task.item`` (raising its error), called once
        any check that needs no parse (its music unreadable) has passed. Raise DancedataError
        to refuse the sequence. Called in input order."""
        raise NotImplementedError

    def finish(self, records: list[SequenceRecord], totals: IngestTotals) -> Finished:
        """The music table, other tables, counts and group attrs of the records read."""
        raise NotImplementedError

    # -- optional: under the store lock -----------------------------------------------------
    def under_lock(self, store: str | Path) -> list[str] | CommandResult:
        """Called once the store lock is held: extra fingerprint lines that depend on the
        store (the version appended to; the plan's ``fingerprint_before_lock`` is then False),
        or a result when there is nothing to do."""
        return []

    def prepare(self, checksums: InputChecksums, skips: SkipPolicy) -> list[ReadTask] | None:
        """Input work needed only when there is something to ingest (music headers, tempo).
        Returns the tasks still to read when it dropped some (skipped inputs), else None."""
        return None

    def open(self, version: VersionWriter, arrays: FrameArrayTarget) -> list[dict[str, Any]]:
        """The version is open: declare arrays known before any record, copy kept frames;
        returns the sequences rows kept from a parent version, written before the new ones."""
        return []
