"""``dancedata ingest bvh``: BVH files (any rig, any channel order) into a new store version.

Steps: inputs (:mod:`~dancedata.ingest.bvh_inputs`: files, music, tempo, genre, split) →
checksums and fingerprint (same inputs and settings: nothing is written) → music described
(tempo estimated where not given) → per file, read and process
(:mod:`~dancedata.ingest.bvh_motion`) and stream into the version's arrays → tables → commit.

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
once this command holds the store lock (see :mod:`dancedata.ingest.locked`): an append queued
behind another writer adds to that writer's version.

Collections: a folder among the paths stands for every file below it matching ``glob``
(:func:`~dancedata.ingest.bvh_inputs.expand_folders`). Files are read and processed as resumable
units of :data:`READ_BATCH_FILES` files (:class:`~dancedata.exec.reads.ResumableReads`, as
``ingest aist`` reads its pickles), on ``workers`` processes; a killed run leaves its finished
units in the version's build area and the next run with the same inputs and settings reads only
the others. The stored bytes do not depend on ``workers``.

Arrays and attrs are described in docs/STORE.md ("BVH stores").
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Any

from dancedata._version import __version__
from dancedata.compute.bvh_units import parse_units
from dancedata.errors import DancedataError, InputError
from dancedata.exec.executors import make_executor
from dancedata.ingest.bvh_arrays import SOURCE, BvhArrayStream
from dancedata.ingest.bvh_inputs import DEFAULT_GLOB, BvhInput, resolve_inputs
from dancedata.ingest.bvh_motion import BvhMotion, BvhSettings, process_bvh
from dancedata.ingest.locked import already_ingested
from dancedata.ingest.resumable_reads import ResumableReads
from dancedata.ingest.run_state import IngestRun
from dancedata.io.bvh_attrs import is_bvh_skeleton
from dancedata.io.bvh_head import FPS_RANGE
from dancedata.progress import progress
from dancedata.store.checksums import fingerprint
from dancedata.store.command_result import CommandResult
from dancedata.store.contract import build_table
from dancedata.store.layout import StoreLayout
from dancedata.store.reader import VersionReader
from dancedata.store.writer import VersionWriter, base_fingerprint, hold_store_lock

__all__ = ["COMMAND", "BvhIngestOptions", "ingest_bvh"]

COMMAND = "ingest bvh"
# Files per resumable read unit: a killed run loses at most this many files' work.
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
        workers: processes reading files (not fingerprinted: the bytes do not depend on it).
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


# ----------------------------------------------------------------------------- the run


@dataclass(kw_only=True)
class _Run(IngestRun):
    options: BvhIngestOptions


def _checked_inputs(run: _Run, inputs: list[BvhInput]) -> tuple[list[BvhInput], list[str]]:
    """Inputs whose files exist, and the fingerprint line of each."""
    kept, keys = [], []
    for item in progress(inputs, "checksums", unit="file"):
        try:
            bvh = run.sha(item.path)
            music = run.sha(item.music) if item.music is not None else None
        except InputError as exc:
            run.fail_or_skip(exc, item.path)
            continue
        kept.append(item)
        keys.append(
            f"{item.seq_id}|bvh={bvh}|music={music}|bpm={item.bpm}|genre={item.genre}"
            f"|split={item.split}"
        )
    if not kept:
        raise InputError("every BVH file was skipped; nothing to ingest")
    return kept, keys


@dataclass
class _Parent:
    """What an appended-to version contributes."""

    reader: VersionReader
    attrs: dict[str, Any]
    rows: list[dict[str, Any]]
    music: list[dict[str, Any]]
    splits: list[dict[str, Any]]

    @property
    def fps(self) -> float:
        return float(self.attrs["fps"])


def _parent(store: str | Path, layout: StoreLayout) -> _Parent:
    if not layout.exists():
        raise InputError("--append needs an existing store", store)
    reader = VersionReader(store)
    attrs = reader.group_attrs("motion")
    if attrs.get("source") != SOURCE or not is_bvh_skeleton(attrs.get("skeleton")):
        raise InputError(
            f"--append adds to a BVH store, but version {reader.version} holds "
            f"{attrs.get('source') or 'another kind of'} data; ingest without --append or into "
            "another store",
            store,
        )
    return _Parent(
        reader=reader,
        attrs=attrs,
        rows=reader.table("sequences").to_pylist(),
        music=reader.table("music").to_pylist() if reader.has_table("music") else [],
        splits=reader.table("splits").to_pylist() if reader.has_table("splits") else [],
    )


def _already_appended(
    parent: _Parent, inputs: list[BvhInput], run: _Run, config: dict[str, Any]
) -> bool:
    """The parent was made by this command with these settings and already holds every input
    (same sequence id and content): appending them again has nothing to do."""
    if parent.reader.manifest.get("command") != COMMAND:
        return False
    old = {k: v for k, v in parent.reader.manifest.get("config", {}).items() if k != "append"}
    if old != {k: v for k, v in config.items() if k != "append"}:
        return False
    held = {r["seq_id"]: r for r in parent.rows}

    def same(item: BvhInput) -> bool:
        row = held.get(item.seq_id)
        return (
            row is not None
            and row["sha256"] == run.sha(item.path)
            and row["genre"] == item.genre
            and (item.bpm is None or row["bpm"] == item.bpm)
            and (row["music_id"] is None) == (item.music is None)
        )

    return all(same(item) for item in inputs)


def _tracks(run: _Run, inputs: list[BvhInput]) -> tuple[list[BvhInput], dict[str, Any]]:
    """Describe each music file once (tempo estimated when no bpm is given)."""
    from dancedata.ingest.video_music import music_from_file

    tracks: dict[str, Any] = {}
    kept = []
    paired = sum(item.music is not None for item in inputs)
    for item in progress(inputs, "read music", total=paired, unit="file") if paired else inputs:
        if item.music is not None and str(item.music) not in tracks:
            try:
                tracks[str(item.music)] = music_from_file(item.music, run.sha(item.music), item.bpm)
            except InputError as exc:
                run.fail_or_skip(exc, item.music)
                continue
        kept.append(item)
    return kept, tracks


# ----------------------------------------------------------------------------- tables


@dataclass(frozen=True)
class _Done:
    """What the tables need of an ingested file (its arrays are already written)."""

    item: BvhInput
    frame_start: int
    n_frames: int
    fps: float
    source_fps: float
    source_frames: int
    source_frame_time_s: float
    size_m: float
    declared_frames: int | None

    @classmethod
    def of(cls, item: BvhInput, motion: BvhMotion, frame_start: int) -> _Done:
        return cls(
            item,
            frame_start,
            motion.n_frames,
            motion.fps,
            motion.source_fps,
            motion.source_frames,
            motion.source_frame_time_s,
            motion.size_m,
            motion.declared_frames,
        )


def _sequence_row(
    done: _Done, music: dict[str, Any] | None, bpm_estimated: bool, sha256: str
) -> dict[str, Any]:
    item, n = done.item, done.n_frames
    music_frames = None if music is None else music["frame_stop"] - music["frame_start"]
    bpm = item.bpm if item.bpm is not None else (music["bpm"] if music else None)
    return {
        "seq_id": item.seq_id,
        "source": SOURCE,
        "genre": item.genre,
        "situation": None,
        "dancer": None,
        "music_id": None if music is None else music["music_id"],
        "choreo": None,
        "bpm": bpm,
        "fps": done.fps,
        "n_frames": n,
        "frame_start": done.frame_start,
        "frame_stop": done.frame_start + n,
        "audio_offset": 0,
        "audio_frames": 0 if music_frames is None else min(n, music_frames),
        "audio_truncated_frames": 0 if music_frames is None else max(0, music_frames - n),
        "music_missing": music is None,
        "bpm_estimated": None if bpm is None else (item.bpm is None and bpm_estimated),
        "source_fps": done.source_fps,
        "source_frames": done.source_frames,
        "source_frame_time_s": done.source_frame_time_s,
        "rig_size_m": done.size_m,
        "path": str(item.path),
        "sha256": sha256,
    }


def _music_table(
    parent_music: list[dict[str, Any]], tracks: dict[str, Any], used: list[BvhInput], fps: float
) -> tuple[list[dict[str, Any]], dict[str, dict[str, Any]]]:
    """Parent rows (re-packed from 0) then one row per new track; rows keyed by file path."""
    rows: list[dict[str, Any]] = []
    by_path: dict[str, dict[str, Any]] = {}
    start = 0
    for old in parent_music:
        row = dict(old)
        n = int(row["frame_stop"]) - int(row["frame_start"])
        row["frame_start"], row["frame_stop"] = start, start + n
        start += n
        rows.append(row)
        by_path[str(row["path"])] = row
    by_sha = {row["sha256"]: row for row in rows}
    ids = {row["music_id"] for row in rows}
    for item in used:
        if item.music is None or str(item.music) in by_path:
            continue
        track = tracks[str(item.music)]
        if track.sha256 in by_sha:  # the same audio under another path
            by_path[str(item.music)] = by_sha[track.sha256]
            continue
        row = track.row(item.genre, start, fps)
        if row["music_id"] in ids:
            row["music_id"] = f"{track.music_id}-{track.sha256[:8]}"
        ids.add(row["music_id"])
        start = row["frame_stop"]
        rows.append(row)
        by_path[str(item.music)] = by_sha[track.sha256] = row
    return rows, by_path


def _write_tables(
    version: VersionWriter,
    parent: _Parent | None,
    done: list[_Done],
    tracks: dict[str, Any],
    fps: float,
    run: _Run,
) -> int:
    """sequences, music and splits tables; returns the number of music tracks."""
    used = [d.item for d in done]
    music_rows, by_path = _music_table(parent.music if parent else [], tracks, used, fps)
    rows = list(parent.rows) if parent else []
    for d in done:
        music = by_path.get(str(d.item.music)) if d.item.music is not None else None
        track = tracks.get(str(d.item.music)) if d.item.music is not None else None
        estimated = bool(track and track.bpm_estimated)
        rows.append(_sequence_row(d, music, estimated, run.sha(d.item.path)))
    splits = list(parent.splits) if parent else []
    splits += [
        {"scheme": "custom", "split": item.split, "seq_id": item.seq_id}
        for item in used
        if item.split is not None
    ]
    version.write_table("sequences", build_table("sequences", rows))
    if music_rows:
        version.write_table("music", build_table("music", music_rows))
    version.write_table("splits", build_table("splits", splits))
    return len(music_rows)


# ----------------------------------------------------------------------------- the command


def _check_new_ids(parent: _Parent, inputs: list[BvhInput]) -> None:
    present = {r["seq_id"] for r in parent.rows}
    for item in inputs:
        if item.seq_id in present:
            raise InputError(
                f"sequence {item.seq_id!r} is already in version {parent.reader.version}; "
                "rename the file, or ingest without --append",
                item.path,
            )


def _read_file(item: tuple[str, BvhSettings]) -> BvhMotion:
    """One read-unit item (top level: process pools pickle it): a file read and processed."""
    path, settings = item
    return process_bvh(Path(path), settings)


def _ingest_files(
    stream: BvhArrayStream,
    inputs: list[BvhInput],
    settings: BvhSettings,
    run: _Run,
    reads: ResumableReads,
) -> list[_Done]:
    """Stream every file's processed arrays in input order; bad ones fail the run or are
    skipped."""
    done: list[_Done] = []
    # reads first: it runs the read units (their own bar) before yielding anything
    for loaded, item in zip(reads, progress(inputs, "ingest BVH", unit="file"), strict=True):
        try:
            motion = loaded.get()
            stream.check(motion, item.path)
        except DancedataError as exc:
            run.fail_or_skip(exc, item.path)
            continue
        start = stream.add(
            motion, item.seq_id, settings.units.name, settings.units.metres, item.path
        )
        done.append(_Done.of(item, motion, start))
    return done


def ingest_bvh(
    store: str | Path, paths: list[str | Path], options: BvhIngestOptions
) -> CommandResult:
    """Ingest BVH ``paths`` (and/or ``options.manifest``) into a new version of ``store``."""
    options.check()
    settings = options.settings()
    inputs = resolve_inputs(
        [Path(p) for p in paths],
        music=options.music,
        bpm=options.bpm,
        genre=options.genre,
        manifest=options.manifest,
        glob=options.glob,
    )
    run = _Run(on_error=options.on_error, options=options)
    inputs, keys = _checked_inputs(run, inputs)
    if options.append and not StoreLayout(store).exists():
        raise InputError("--append needs an existing store", store)
    # No lost update: the version appended to, the parent, the fingerprint (which names the
    # version appended to) and the "already done" checks are read under the store lock, so an
    # append that waited behind another writer appends to that writer's result.
    with hold_store_lock(store, wait=options.wait_for_lock, create=not options.append) as lock:
        return _ingest_locked(store, inputs, keys, run, settings, lock)


def _ingest_locked(
    store: str | Path,
    inputs: list[BvhInput],
    keys: list[str],
    run: _Run,
    settings: BvhSettings,
    lock: Any,
) -> CommandResult:
    options = run.options
    layout = StoreLayout(store)
    config = options.config()
    parent = _parent(store, layout) if options.append else None
    if parent is not None:
        if _already_appended(parent, inputs, run, config):
            return CommandResult(version=parent.reader.version, created=False)
        _check_new_ids(parent, inputs)
        keys.append(f"append-to={base_fingerprint(parent.reader.manifest)}")
    fp = fingerprint(COMMAND, config, keys, __version__)
    ingested = already_ingested(store, fp)
    if ingested is not None:
        return ingested
    inputs, tracks = _tracks(run, inputs)

    with (
        make_executor(options.workers) as executor,
        VersionWriter(
            store,
            command=COMMAND,
            config=config,
            fingerprint=fp,
            inputs=list(run.described.values()),
            parent=layout.latest() if layout.exists() else None,
            carry_over=False,
            wait_for_lock=options.wait_for_lock,
            stage="ingest",
            resumable=True,
            lock=lock,
            based_on=parent.reader.version if parent else None,  # (read under this same lock)
        ) as version,
    ):
        # resume: keep the read units a killed run finished, rebuild every output.
        version.reset_outputs()
        version.mark_prepared()
        reads = ResumableReads(
            version.build_area(),
            "bvh",
            [(str(item.path), settings) for item in inputs],
            _read_file,
            batch_size=READ_BATCH_FILES,
            executor=executor,
            desc="read BVH files",
        )
        stream = BvhArrayStream(version, options.up_axis, options.skeleton_atol_m)
        if parent is not None:
            stream.copy_parent(
                parent.reader, max((r["frame_stop"] for r in parent.rows), default=0)
            )
        done = _ingest_files(stream, inputs, settings, run, reads)
        stream.close()
        if not done:
            raise InputError("every BVH file was skipped; nothing to ingest")
        for item in run.skipped:
            version.skip(item["path"], item["error"])
        n_music = _write_tables(version, parent, done, tracks, float(stream.fps), run)
        counts = {
            "sequences": len(parent.rows if parent else []) + len(done),
            "frames": stream.frames,
            "new_sequences": len(done),
            "new_frames": sum(d.n_frames for d in done),
            "appended_to": parent.reader.version if parent else None,
            "music": n_music,
            "fps": stream.fps,
            "joints": stream.skeleton.n_joints if stream.skeleton else 0,
            "skipped": len(version.skipped),
            "files": {
                d.item.seq_id: {
                    "source_fps": d.source_fps,
                    "source_frames": d.source_frames,
                    "frames": d.n_frames,
                    "rig_size_m": round(d.size_m, 4),
                }
                | (
                    {"declared_frames": d.declared_frames}
                    if d.declared_frames != d.source_frames
                    else {}
                )
                for d in done
            },
            **reads.counts(),
        }
        name = version.commit(counts=counts)
    return CommandResult(version=name, created=True, counts=counts, skipped=version.skipped)
