"""The ingest engine: one run of any source (:mod:`dancedata.ingest.source`) into a new version.

``ingest(store, source)`` does, for every source, in this order:

1. ``source.plan(store, checksums, skips)``: inputs, their checksums, the read tasks and the
   arrays (a store the source cannot write is refused here);
2. the fingerprint (command, config, the plan's lines, package version); a committed version
   carrying it means nothing to do (asked before the lock when the plan allows, and again
   under it: see "No lost update" below);
3. the store lock (``create_store``), ``source.under_lock``
   (``--append``: the parent, more fingerprint lines), ``source.prepare`` (music headers,
   tempo; may drop tasks whose inputs it skipped);
4. a resumable :class:`~dancedata.store.writer.VersionWriter` (its parent: the latest version
   now); the read tasks run on the executor (serial, process pool or Dask) as resumable batches
   (:mod:`dancedata.ingest.resumable_reads`): a killed run's finished batches are not read
   again, and each batch is packed (step 5) as soon as it and those before it are read;
5. ``source.open`` (a parent's frames and rows kept); in input order,
   ``source.read(task, parsed)`` → a :class:`SequenceRecord`; a DancedataError from it or from
   the parse fails the run or, with ``--on-error skip``, is recorded in the manifest's
   ``skipped`` list; the record's arrays are appended to the version's frame-concatenated
   arrays (the plan's ``arrays``, declared at the first record), and its ``frame_start`` is the
   number of frames before it;
6. ``source.finish`` → the tables: ``sequences`` (the kept rows, then :func:`sequence_row` of
   each record, the one place a sequence row is built), ``music``, then the source's other
   tables (splits, cameras), the group attrs and the counts; then the commit.

Stored bytes depend only on the inputs and the settings, never on the number of workers.

No lost update (issue 11, item 3): an ingest that had to wait for the lock must not write the
version it planned before waiting. So, once it holds the lock, it looks again for a committed
version carrying its fingerprint (:func:`already_ingested`: a writer it waited behind may have
just ingested the same data, and then it writes nothing), takes the latest version *now* as its
parent (:func:`latest_version`), and ``--append`` reads the version it appends to only now, so
the other writer's version is kept. Reading the inputs (hashing, decoding) depends on no store
state and happens before the lock.
"""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np

from dancedata._version import __version__
from dancedata.errors import DancedataError
from dancedata.exec.executors import make_executor
from dancedata.ingest.resumable_reads import ResumableReads
from dancedata.ingest.source import (
    FrameArrayTarget,
    IngestPlan,
    IngestTotals,
    InputChecksums,
    ReadTask,
    SequenceRecord,
    SkipPolicy,
    Source,
    StoredArray,
)
from dancedata.progress import progress
from dancedata.store.arrays import FrameArrayWriter
from dancedata.store.backend import StoreBackend
from dancedata.store.backend_open import make_backend
from dancedata.store.checksums import fingerprint
from dancedata.store.command_result import CommandResult
from dancedata.store.contract import build_table
from dancedata.store.layout import StoreLayout
from dancedata.store.seq_ids import check_seq_id
from dancedata.store.writer import VersionWriter, find_version_with_fingerprint, hold_store_lock

__all__ = ["FrameArrays", "already_ingested", "ingest", "latest_version", "sequence_row"]


def latest_version(store: str | Path) -> str | None:
    """The store's latest committed version, None for a new or empty store."""
    layout = StoreLayout(store)
    return layout.latest() if layout.exists() else None


def already_ingested(store: str | Path, fp: str) -> CommandResult | None:
    """A "nothing to do" result when a committed version already holds this ingest's result.

    Authoritative only under the lock. Before it, a version found is still a right answer
    (committed versions never change), so callers may ask first to skip reading inputs; a
    version *not* found must be asked again under the lock.
    """
    existing = find_version_with_fingerprint(store, fp)
    if existing is None:
        return None
    return CommandResult(version=existing, created=False, latest=latest_version(store))


class FrameArrays(FrameArrayTarget):
    """The version's frame-concatenated arrays, one streaming writer per declared array."""

    def __init__(self, version: VersionWriter) -> None:
        self.root = version.zarr_group()
        self.root.require_group("motion")
        self.root.require_group("audio")
        self.writers: dict[str, FrameArrayWriter] = {}
        self.declared = False
        self.frames = 0

    def declare(self, specs: Sequence[StoredArray]) -> None:
        """Create the arrays (empty, in this order)."""
        for spec in specs:
            self.writers[spec.name] = FrameArrayWriter(
                self.root.require_group(spec.group),
                spec.name,
                spec.row_shape,
                spec.dtype,
                attrs=spec.attrs,
                compressors=spec.compressors,
                chunks_per_write=spec.chunks_per_write,
            )
        self.declared = True

    def append(self, arrays: dict[str, np.ndarray], n_frames: int | None = None) -> None:
        """Append one block of rows to every declared array: exactly the declared names, all
        ``n_frames`` long (when given; else all of one length)."""
        if set(arrays) != set(self.writers):
            raise ValueError(
                f"a record's arrays {sorted(arrays)} are not the declared {sorted(self.writers)}"
            )
        lengths = {len(block) for block in arrays.values()}
        if len(lengths) > 1 or (n_frames is not None and lengths and lengths != {n_frames}):
            raise ValueError(f"a record's arrays hold {sorted(lengths)} rows, not {n_frames}")
        for name, writer in self.writers.items():
            writer.append(arrays[name])
        # A source without frame arrays (music alone) still places its sequences on the
        # frame axis, one after the other, so frame ranges stay contiguous.
        self.frames += lengths.pop() if lengths else (n_frames or 0)

    def close(self, group_attrs: dict[str, dict[str, Any]]) -> None:
        for writer in self.writers.values():
            writer.close()
        for group, attrs in group_attrs.items():
            if attrs:
                self.root.require_group(group).attrs.update(attrs)


def sequence_row(record: SequenceRecord, music: dict[str, Any] | None) -> dict[str, Any]:
    """The ``sequences`` table row of a record placed at ``record.frame_start``, and how its
    music (its ``music`` table row, None when it has none) covers it: ``audio_frames`` motion
    frames have music, ``audio_truncated_frames`` music frames run past the motion's end.
    Music starts with the motion (``audio_offset`` 0)."""
    n = record.n_frames
    music_frames = None if music is None else int(music["frame_stop"] - music["frame_start"])
    bpm = record.bpm if record.bpm is not None else (music["bpm"] if music else None)
    row: dict[str, Any] = {
        "seq_id": record.seq_id,
        "source": record.source,
        "genre": record.genre,
        "situation": record.situation,
        **record.name_columns,
        "dancer": record.dancer,
        "music_id": music["music_id"] if music is not None else record.music_id,
        "choreo": record.choreo,
        "bpm": bpm,
        "fps": record.fps,
        "n_frames": n,
        "frame_start": record.frame_start,
        "frame_stop": record.frame_start + n,
        "audio_offset": 0,
        "audio_frames": 0 if music_frames is None else min(n, music_frames),
        "audio_truncated_frames": 0 if music_frames is None else max(0, music_frames - n),
        "music_missing": music is None,
    }
    if record.bpm_estimated is not None:
        row["bpm_estimated"] = None if bpm is None else record.bpm_estimated
    row.update(record.columns)
    row["path"] = record.path
    row["sha256"] = record.sha256
    return row


def ingest(store: str | Path | StoreBackend, source: Source) -> CommandResult:
    """Ingest what ``source`` plans into a new version of ``store`` (see the module docstring);
    a "nothing to do" result when a committed version already holds it. A path is resolved
    into its backend once, here; the source's hooks, the lock and the writer take that."""
    store = make_backend(store)
    checksums = InputChecksums()
    skips = SkipPolicy(source.on_error)
    plan = source.plan(store, checksums, skips)
    if plan.fingerprint_before_lock:
        fp = fingerprint(source.command, plan.config, plan.fingerprint_keys, __version__)
        ingested = already_ingested(store, fp)  # (asked again under the lock)
        if ingested is not None:
            return ingested
    with hold_store_lock(store, wait=plan.wait_for_lock, create=plan.create_store) as lock:
        locked = source.under_lock(store)
        if isinstance(locked, CommandResult):
            return locked
        fp = fingerprint(source.command, plan.config, plan.fingerprint_keys + locked, __version__)
        ingested = already_ingested(store, fp)  # by a writer this one waited for
        if ingested is not None:
            return ingested
        kept = source.prepare(checksums, skips)
        tasks = plan.tasks if kept is None else kept
        inputs = plan.inputs if plan.inputs is not None else checksums.inputs()
        return _write_version(store, source, plan, tasks, inputs, fp, lock, skips)


def _write_version(
    store: StoreBackend,
    source: Source,
    plan: IngestPlan,
    tasks: list[ReadTask],
    inputs: list[dict[str, Any]],
    fp: str,
    lock: Any,
    skips: SkipPolicy,
) -> CommandResult:
    with (
        make_executor(plan.workers, plan.dask) as executor,
        VersionWriter(
            store,
            command=source.command,
            config=plan.config,
            fingerprint=fp,
            inputs=inputs,
            parent=latest_version(store),
            carry_over=False,
            wait_for_lock=plan.wait_for_lock,
            stage="ingest",
            resumable=plan.resumable,
            lock=lock,
            based_on=source.based_on,  # (set by under_lock: read under this same lock)
        ) as version,
    ):
        # resume: keep the read batches a killed run finished, rebuild every output.
        version.reset_outputs()
        version.mark_prepared()
        arrays = FrameArrays(version)
        kept = source.open(version, arrays)
        kept_frames = arrays.frames
        reads = ResumableReads(
            version.build_area(),
            plan.task_kind,
            [task.item for task in tasks],
            plan.parse,
            batch_size=plan.batch_size,
            executor=executor,
            desc=plan.read_desc,
        )
        records: list[SequenceRecord] = []
        # reads first: it starts the read tasks (their own bar) before yielding anything
        in_order = progress(tasks, plan.sequences_desc, unit=plan.sequences_unit)
        for result, task in zip(reads, in_order, strict=True):
            try:
                record = source.read(task, result.get)
                check_seq_id(record.seq_id, task.path)
            except DancedataError as exc:
                skips.fail_or_skip(exc, task.path)
                continue
            if not arrays.declared:
                arrays.declare(plan.arrays(record) if callable(plan.arrays) else plan.arrays)
            record.frame_start = arrays.frames
            arrays.append(record.arrays, record.n_frames)
            record.arrays = {}  # written: memory holds one sequence at a time
            records.append(record)
        if not records:
            raise plan.empty_error
        for item in skips.skipped:
            version.skip(item["path"], item["error"])
        totals = IngestTotals(
            frames=arrays.frames,
            new_frames=arrays.frames - kept_frames,
            sequences=len(kept) + len(records),
            skipped=len(version.skipped),
            read_counts=reads.counts(),
        )
        finished = source.finish(records, totals)
        arrays.close(finished.attrs)
        music = finished.music
        rows = kept + [
            sequence_row(r, music.by_key.get(r.music_key) if r.music_key else None) for r in records
        ]
        version.write_table("sequences", build_table("sequences", rows))
        if music.rows or music.write_empty:
            version.write_table("music", build_table("music", music.rows))
        for name, table in finished.tables.items():
            version.write_table(name, build_table(name, table))
        counts = finished.counts
        name = version.commit(counts=counts)
    return CommandResult(version=name, created=True, counts=counts, skipped=version.skipped)
