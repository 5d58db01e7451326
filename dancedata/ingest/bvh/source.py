"""``dancedata ingest bvh``: BVH files (any rig, any channel order) into a new store version.

Steps: inputs (:mod:`~dancedata.ingest.bvh.inputs`: files, music, tempo, genre, split) →
checksums and fingerprint (same inputs and settings: nothing is written) → music described
(tempo estimated where not given) → per file, read and process
(:mod:`~dancedata.ingest.bvh.motion`) and stream into the version's arrays → tables → commit.

One store holds one skeleton: every file must match the first (or, with ``append``, the
store's) in joint names, parents, channel layout, End Sites and offsets (within
``skeleton_atol_m``, on the components no position channel overwrites: see
:func:`~dancedata.io.bvh_attrs.skeleton_mismatch`), and all must share one frame rate (``--fps``
resamples them to one).

Replace or append: by default the new version holds exactly the given files (its parent is
recorded, nothing is carried over), as the other ingest commands do. ``append`` keeps the
latest version's sequences, music and splits and adds the new files after them; the latest
version must be a BVH store with the same skeleton, and sequence ids must not repeat. Either way
the version is an *ingest* stage: featurize and segment run again on it. "Latest" means latest
once this command holds the store lock (:mod:`dancedata.ingest.engine`, "No lost update"): an
append queued behind another writer adds to that writer's version.

Collections: a folder among the paths stands for every file below it matching ``glob``
(:func:`~dancedata.ingest.bvh.inputs.expand_folders`). :class:`BvhSource` is an ingest source
(:mod:`dancedata.ingest.source`): the engine (:mod:`dancedata.ingest.engine`) reads and
processes the files as resumable tasks of :data:`READ_BATCH_FILES` files, as it reads every
source, on ``workers`` processes; a killed run leaves its finished tasks in the version's build
area and the next run with the same inputs and settings reads only the others. The stored bytes
do not depend on ``workers``.

Arrays and attrs are described in docs/STORE.md ("BVH stores").
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from dancedata.compute.bvh_units import parse_units, size_warning
from dancedata.errors import InputError
from dancedata.ingest.bvh.append import (
    AppendedVersion,
    already_appended,
    check_new_ids,
    read_appended_version,
)
from dancedata.ingest.bvh.arrays import SOURCE, BvhRig, copy_parent_frames, motion_arrays
from dancedata.ingest.bvh.inputs import DEFAULT_GLOB, BvhInput, resolve_inputs
from dancedata.ingest.bvh.motion import BvhMotion, BvhSettings, process_bvh
from dancedata.ingest.bvh.music import music_table_rows, music_tracks
from dancedata.ingest.engine import ingest
from dancedata.ingest.registry import register_source
from dancedata.ingest.source import (
    Finished,
    FrameArrayTarget,
    IngestPlan,
    IngestTotals,
    InputChecksums,
    MusicTable,
    ReadTask,
    SequenceRecord,
    SkipPolicy,
    Source,
)
from dancedata.io.bvh_head import FPS_RANGE
from dancedata.progress import progress
from dancedata.store.command_result import CommandResult
from dancedata.store.layout import StoreLayout, warn_once
from dancedata.store.writer import VersionWriter, base_fingerprint

__all__ = ["COMMAND", "BvhIngestOptions", "BvhSource", "ingest_bvh"]

COMMAND = "ingest bvh"
# Files per resumable read task: a killed run loses at most this many files' work.
READ_BATCH_FILES = 8
_FRAMES_MODES = ("declared", "present")


@dataclass
class BvhIngestOptions:
    """Settings of one BVH ingest (all but ``wait_for_lock`` are fingerprinted).

    Attributes:
        units: the files' length unit (cm, m, mm, in, ft, dm) or metres per unit.
        fps: resample every file to this rate (frames/s); None keeps the files' rate.
        smooth_cutoff_hz, smooth_order: Butterworth smoothing of joint rotations.
        check_size: refuse rigs whose size is implausible in metres (wrong ``units``).
        up_axis: recorded in the motion attrs ("y" for nearly every BVH file).
        music, bpm, genre: pairing for a single file (bpm and genre apply to every file).
        manifest: CSV pairing files with music, bpm, genre and split.
        append: add to the latest version's sequences instead of replacing them.
        skeleton_atol_m: tolerance on offsets when comparing skeletons, metres.
        on_error: "fail" or "skip" (skip a bad file and record why in the manifest).
        frames: "declared" (a MOTION block with another row count than ``Frames:`` is refused)
            or "present" (every row is a frame; each file's declared and read counts go into
            the manifest's counts).
        glob: file-name pattern for folders given as paths (searched recursively).
        workers: processes reading files; dask: a Dask scheduler address or "local:N" instead
            (neither is fingerprinted: the bytes do not depend on them).
    """

    units: str = "cm"
    fps: float | None = None
    smooth_cutoff_hz: float | None = None
    smooth_order: int = 2
    check_size: bool = True
    up_axis: str = "y"
    music: Path | None = None
    bpm: float | None = None
    genre: str | None = None
    manifest: Path | None = None
    append: bool = False
    skeleton_atol_m: float = 1e-4
    on_error: str = "fail"
    wait_for_lock: bool = False
    frames: str = "declared"
    glob: str = DEFAULT_GLOB
    workers: int = 1
    dask: str | None = None

    def settings(self) -> BvhSettings:
        return BvhSettings(
            units=parse_units(self.units),
            fps=self.fps,
            smooth_cutoff_hz=self.smooth_cutoff_hz,
            smooth_order=self.smooth_order,
            check_size=self.check_size,
            frames=self.frames,
        )

    def check(self) -> None:
        low, high = FPS_RANGE
        if self.fps is not None and not low <= self.fps <= high:
            raise InputError(
                f"--fps must lie in {low:g} to {high:,.0f} frames per second, not {self.fps:g}"
            )
        if self.smooth_cutoff_hz is not None and not self.smooth_cutoff_hz > 0:
            raise InputError(f"--smooth-cutoff must be positive, not {self.smooth_cutoff_hz}")
        if self.smooth_order < 1:
            raise InputError(f"--smooth-order must be at least 1, not {self.smooth_order}")
        if self.up_axis not in ("x", "y", "z", "-x", "-y", "-z"):
            raise InputError(f"--up-axis must be x, y or z (optionally with -), not {self.up_axis}")
        if self.frames not in _FRAMES_MODES:
            raise InputError(f"--frames must be declared or present, not {self.frames!r}")
        if self.workers < 1:
            raise InputError(f"--workers must be at least 1, not {self.workers}")
        if self.on_error not in ("fail", "skip"):
            raise InputError(f"on_error must be 'fail' or 'skip', not {self.on_error!r}")

    def config(self) -> dict[str, Any]:
        return {
            "source": SOURCE,
            **self.settings().config(),
            "up_axis": self.up_axis,
            "skeleton_atol_m": self.skeleton_atol_m,
            "append": self.append,
            "audio_offset": 0,
            "on_error": self.on_error,
        }


# ----------------------------------------------------------------------------- inputs


def _checked_inputs(
    inputs: list[BvhInput], checksums: InputChecksums, skips: SkipPolicy
) -> tuple[list[BvhInput], list[str]]:
    """Inputs whose files exist, and the fingerprint line of each."""
    kept, keys = [], []
    for item in progress(inputs, "checksums", unit="file"):
        try:
            bvh = checksums.sha(item.path)
            music = checksums.sha(item.music) if item.music is not None else None
        except InputError as exc:
            skips.fail_or_skip(exc, item.path)
            continue
        kept.append(item)
        keys.append(
            f"{item.seq_id}|bvh={bvh}|music={music}|bpm={item.bpm}|genre={item.genre}"
            f"|split={item.split}"
        )
    if not kept:
        raise InputError("every BVH file was skipped; nothing to ingest")
    return kept, keys


# ----------------------------------------------------------------------------- the source


def _read_file(item: tuple[str, BvhSettings]) -> BvhMotion:
    """One read-task item (top level: process pools pickle it): a file read and processed."""
    path, settings = item
    return process_bvh(Path(path), settings)


@register_source("bvh")
class BvhSource(Source):
    """BVH files (and/or a manifest CSV) as engine records (:mod:`dancedata.ingest.source`);
    see the module docstring."""

    command = COMMAND

    def __init__(self, paths: list[str | Path], options: BvhIngestOptions) -> None:
        options.check()
        self.paths = [Path(p) for p in paths]
        self.options = options
        self.on_error = options.on_error
        self.settings = options.settings()
        self.config = options.config()
        self.rig = BvhRig(options.up_axis, options.skeleton_atol_m)
        self.parent: AppendedVersion | None = None
        self.tracks: dict[str, Any] = {}

    # -- before the version opens ----------------------------------------------------------
    def plan(self, store: str | Path, checksums: InputChecksums, skips: SkipPolicy) -> IngestPlan:
        options = self.options
        resolved = resolve_inputs(
            self.paths,
            music=options.music,
            bpm=options.bpm,
            genre=options.genre,
            manifest=options.manifest,
            glob=options.glob,
        )
        self.checksums = checksums
        self.inputs, keys = _checked_inputs(resolved, checksums, skips)
        if options.append and not StoreLayout(store).exists():
            raise InputError("--append needs an existing store", store)
        return IngestPlan(
            config=self.config,
            fingerprint_keys=keys,
            inputs=None,  # every file described through checksums, when the version opens
            tasks=self._tasks(self.inputs),
            parse=_read_file,
            task_kind="bvh",
            arrays=lambda first: self.rig.array_specs(),
            read_desc="read BVH files",
            sequences_desc="ingest BVH",
            sequences_unit="file",
            batch_size=READ_BATCH_FILES,
            workers=options.workers,
            dask=options.dask,
            wait_for_lock=options.wait_for_lock,
            create_store=not options.append,
            fingerprint_before_lock=not options.append,  # it names the version appended to
            empty_error=InputError("every BVH file was skipped; nothing to ingest"),
        )

    def _tasks(self, inputs: list[BvhInput]) -> list[ReadTask]:
        return [ReadTask(str(item.path), (str(item.path), self.settings)) for item in inputs]

    def under_lock(self, store: str | Path) -> list[str] | CommandResult:
        """``--append``: the latest version once the lock is held, so an append that waited
        behind another writer appends to that writer's result."""
        if not self.options.append:
            return []
        parent = self.parent = read_appended_version(store, StoreLayout(store))
        if already_appended(parent, self.inputs, self.checksums, self.config, COMMAND):
            return CommandResult(version=parent.reader.version, created=False)
        check_new_ids(parent, self.inputs)
        self.based_on = parent.reader.version
        return [f"append-to={base_fingerprint(parent.reader.manifest)}"]

    def prepare(self, checksums: InputChecksums, skips: SkipPolicy) -> list[ReadTask]:
        """Describe the music (tempo); files whose music is unreadable are skipped or fail."""
        self.inputs, self.tracks = music_tracks(self.inputs, checksums, skips)
        self.by_path = {str(item.path): item for item in self.inputs}
        return self._tasks(self.inputs)

    # -- writing ---------------------------------------------------------------------------
    def open(self, version: VersionWriter, arrays: FrameArrayTarget) -> list[dict[str, Any]]:
        if self.parent is None:
            return []
        reader = self.parent.reader
        self.rig.adopt_parent(reader)
        n_frames = max((r["frame_stop"] for r in self.parent.rows), default=0)
        copy_parent_frames(reader, arrays, self.rig.array_specs(), n_frames)
        return list(self.parent.rows)

    def read(self, task: ReadTask, parsed: Callable[[], Any]) -> SequenceRecord:
        item, motion, units = self.by_path[task.path], parsed(), self.settings.units
        self.rig.check(motion, item.path)
        unusual = size_warning(motion.size_m, units) if self.settings.check_size else None
        if unusual is not None:
            warn_once(f"{item.path}: {unusual}")
        self.rig.adopt_first(motion, item.seq_id, units.name, units.metres, item.path)
        track = self.tracks.get(str(item.music)) if item.music is not None else None
        return SequenceRecord(
            seq_id=item.seq_id,
            source=SOURCE,
            path=str(item.path),
            sha256=self.checksums.sha(item.path),
            fps=motion.fps,
            n_frames=motion.n_frames,
            arrays=motion_arrays(motion),
            genre=item.genre,
            music_key=None if item.music is None else str(item.music),
            bpm=item.bpm,
            bpm_estimated=item.bpm is None and bool(track and track.bpm_estimated),
            columns={
                "source_fps": motion.source_fps,
                "source_frames": motion.source_frames,
                "source_frame_time_s": motion.source_frame_time_s,
                "rig_size_m": motion.size_m,
            },
            item=(item, motion.declared_frames),
        )

    # -- tables ----------------------------------------------------------------------------
    def finish(self, records: list[SequenceRecord], totals: IngestTotals) -> Finished:
        used = [r.item[0] for r in records]
        parent_music = self.parent.music if self.parent else []
        rows, by_path = music_table_rows(parent_music, self.tracks, used, float(self.rig.fps or 0))
        splits = list(self.parent.splits) if self.parent else []
        splits += [
            {"scheme": "custom", "split": item.split, "seq_id": item.seq_id}
            for item, _ in (r.item for r in records)
            if item.split is not None
        ]
        return Finished(
            music=MusicTable(rows, by_path),
            counts=self._counts(records, totals, len(rows)),
            tables={"splits": splits},
            attrs={"motion": self.rig.attrs},
        )

    def _counts(
        self, records: list[SequenceRecord], totals: IngestTotals, music: int
    ) -> dict[str, Any]:
        return {
            "sequences": totals.sequences,
            "frames": totals.frames,
            "new_sequences": len(records),
            "new_frames": totals.new_frames,
            "appended_to": self.parent.reader.version if self.parent else None,
            "music": music,
            "fps": self.rig.fps,
            "joints": self.rig.skeleton.n_joints if self.rig.skeleton else 0,
            "skipped": totals.skipped,
            "files": {r.seq_id: _file_counts(r) for r in records},
            **totals.read_counts,
        }


def _file_counts(record: SequenceRecord) -> dict[str, Any]:
    """A file's frame counts for the manifest (declared ones only where they differ)."""
    declared = record.item[1]
    columns = record.columns
    return {
        "source_fps": columns["source_fps"],
        "source_frames": columns["source_frames"],
        "frames": record.n_frames,
        "rig_size_m": round(columns["rig_size_m"], 4),
    } | ({"declared_frames": declared} if declared != columns["source_frames"] else {})


def ingest_bvh(
    store: str | Path, paths: list[str | Path], options: BvhIngestOptions
) -> CommandResult:
    """Ingest BVH ``paths`` (and/or ``options.manifest``) into a new version of ``store``."""
    return ingest(store, BvhSource(paths, options))
