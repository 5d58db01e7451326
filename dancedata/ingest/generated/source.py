"""``dancedata ingest generated``: a model's output folder into a store shaped like a reference.

A source of the ingest engine (registered as "generated"). The folder holds one file per
sequence, named by the sequence id of a *reference* store (``--like``), in any layout
``evaluate --generated`` reads (:mod:`dancedata.io.generated_motion`: FACT 225-d rows, SMPL
``smpl_poses`` + ``smpl_trans`` (Bailando, EDGE, AIST++), joint positions (Bailando's
``np.save`` dict, ``(F, J, 3)`` arrays), or any rig's ``axis_angle`` / ``quat`` + ``trans``);
EDGE's ``<prefix>_<seq_id>.pkl`` names are matched too. Every file is read by the bounded
reader: declared sizes checked before loading (at most twice the reference sequence's frames
plus 1200), pickles by the restricted unpickler.

The version written takes from the reference, by sequence id: the motion group attrs (skeleton,
frame rate, up axis), each sequence's genre, situation, dancer, choreography, music id and
tempo, the music rows of the tracks used (re-packed from frame 0: featurize decodes them), and
the split memberships; ``source`` is ``generated``. A file whose name is no sequence of the
reference, or whose joints do not fit the reference skeleton, is refused (``--on-error skip``
records it). So render, plot, export bvh, featurize and ``evaluate REFERENCE --generated STORE``
work on a model's output.

Arrays: rotation layouts are stored as ``motion/axis_angle`` (F, J, 3) rad and
``motion/trans`` (F, 3) m (FACT matrices projected on the nearest rotation first, quaternions
normalised); position layouts as ``motion/positions`` (F, J, 3) m only. One kind per version.

Conversions before storing, each recorded in the manifest config: ``--generated-up-axis z``
(EDGE: z up → y up), ``--generated-fps`` (resampled to the reference's rate: decimation or
SLERP), then ``--repair-hip-flips`` and ``--smooth-cutoff`` (:mod:`dancedata.compute.
motion_postprocess`). Flips found are listed per sequence in the manifest counts and printed.
"""

from __future__ import annotations

import math
import os
import stat
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from dancedata.compute.motion_postprocess import postprocess_config, postprocess_motion
from dancedata.errors import InputError
from dancedata.ingest.engine import ingest
from dancedata.ingest.registry import register_source
from dancedata.ingest.source import (
    Finished,
    IngestPlan,
    IngestTotals,
    InputChecksums,
    MusicTable,
    ReadTask,
    SequenceRecord,
    SkipPolicy,
    Source,
    StoredArray,
)
from dancedata.io.generated_motion import (
    GENERATED_SUFFIXES,
    MAX_ROW_VALUES,
    generated_frame_limit,
)
from dancedata.store.command_result import CommandResult
from dancedata.store.seq_ids import check_seq_id

__all__ = [
    "GeneratedIngestOptions",
    "GeneratedRead",
    "GeneratedSource",
    "flip_lines",
    "ingest_generated",
    "read_generated",
]

COMMAND = "ingest generated"
# Longest first: Bailando saves <name>.pkl with np.save, so the file is <name>.pkl.npy.
NAME_SUFFIXES = (".pkl.npy", *GENERATED_SUFFIXES)
MAX_FLIP_RUNS_LISTED = 50  # per sequence, in the manifest counts
SEQUENCE_COLUMNS = ("genre", "situation", "dancer", "choreo")


@dataclass(frozen=True)
class GeneratedSettings:
    """What the read of one file does besides reading (picklable: sent to the workers)."""

    fps: float
    generated_fps: float | None = None
    up_axis: str = "y"
    smooth_cutoff: float | None = None
    smooth_order: int = 2
    repair_hip_flips: bool = False
    flip_threshold_deg: float = 90.0


@dataclass
class GeneratedIngestOptions:
    """Settings of an ``ingest generated`` run; all but the lock and worker settings change
    the data.

    Attributes:
        like: the reference store (skeleton, frame rate, music, sequence metadata, splits).
        like_version: its version (default: the latest).
        generated_fps: the files' frame rate; None: the reference's (no resampling).
        up_axis: ``y`` (SMPL, FACT, Bailando) or ``z`` (EDGE), turned to the reference's y up.
        smooth_cutoff: Butterworth cutoff (Hz) of the zero-phase low-pass; None: no smoothing.
        smooth_order: the filter's order per pass (effective order twice that).
        repair_hip_flips: repair half-turn flips of the root rotation.
        flip_threshold_deg: a root rotation step above this per frame is a flip (degrees).
    """

    like: str | Path
    like_version: str | None = None
    generated_fps: float | None = None
    up_axis: str = "y"
    smooth_cutoff: float | None = None
    smooth_order: int = 2
    repair_hip_flips: bool = False
    flip_threshold_deg: float = 90.0
    on_error: str = "fail"
    wait_for_lock: bool = False
    workers: int = 1

    def check(self) -> None:
        if self.up_axis not in ("y", "z"):
            raise InputError(f"--generated-up-axis must be y or z, got {self.up_axis!r}")
        fps = self.generated_fps
        if fps is not None and not (math.isfinite(fps) and 1 <= fps <= 1000):
            raise InputError(f"--generated-fps must be between 1 and 1000, got {fps}")
        if not 1 <= self.smooth_order <= 8:
            raise InputError(f"--smooth-order must be between 1 and 8, got {self.smooth_order}")
        cutoff = self.smooth_cutoff
        if cutoff is not None and not (math.isfinite(cutoff) and cutoff > 0):
            raise InputError(f"--smooth-cutoff must be a positive frequency in Hz, got {cutoff}")
        threshold = self.flip_threshold_deg
        if not (math.isfinite(threshold) and 0 < threshold < 180):
            raise InputError(f"--flip-threshold must be in (0, 180) degrees, got {threshold}")


@dataclass(frozen=True)
class _FileItem:
    path: str
    sha256: str
    seq_id: str
    max_frames: int
    settings: GeneratedSettings


@dataclass(frozen=True)
class GeneratedRead:
    """One generated file read, converted to the reference's frame and post-processed.

    Attributes:
        layout: the file's layout (``fact225``, ``smpl``, ``rotations``, ``positions``).
        source_frames: frames in the file (before resampling).
        axis_angle: (F, J, 3) float32 rad, or None (positions only).
        trans: (F, 3) float32 m, or None.
        positions: (F, J, 3) float32 m, or None (rotation layouts: not stored).
        resampled: the resampling method, or None when the file is at the reference's rate.
        flip_frames, flip_angles_deg: frames turned back by the hip-flip repair and their raw
            steps (empty when none or not asked); flip_runs: [start, stop) of each run.
        flip_summary: the repair's one-line summary, or None when not asked.
    """

    layout: str
    source_frames: int
    axis_angle: np.ndarray | None
    trans: np.ndarray | None
    positions: np.ndarray | None
    resampled: str | None
    flip_frames: np.ndarray
    flip_angles_deg: np.ndarray
    flip_runs: list[list[int]] = field(default_factory=list)
    flip_summary: str | None = None

    @property
    def n_frames(self) -> int:
        array = self.axis_angle if self.axis_angle is not None else self.positions
        return 0 if array is None else int(array.shape[0])


def _rotations(motion: Any) -> tuple[np.ndarray | None, np.ndarray | None]:
    """(axis-angle, translation) of a read file, None for positions-only layouts."""
    from dancedata.compute.rotations import quat_to_axis_angle
    from dancedata.metrics.evaluate_inputs import fact_rows_to_smpl

    if motion.fact_rows is not None:
        return fact_rows_to_smpl(motion.fact_rows)
    if motion.quat is not None:
        quat = motion.quat / np.linalg.norm(motion.quat, axis=-1, keepdims=True)
        return quat_to_axis_angle(quat), motion.trans
    return motion.axis_angle, motion.trans


def read_generated(item: _FileItem) -> GeneratedRead:
    """Read one file (bounded), convert and post-process it: runs in a worker."""
    from dancedata.io.generated_motion import read_generated_motion
    from dancedata.metrics.evaluate_inputs import resample_generated, z_up_to_y_up

    s = item.settings
    motion = read_generated_motion(item.path, item.max_frames)
    axis_angle, trans = _rotations(motion)
    positions = None if axis_angle is not None else motion.positions
    if s.up_axis == "z":
        axis_angle, trans, positions = z_up_to_y_up(axis_angle, trans, positions)
    resampled = None
    src = s.generated_fps or s.fps
    if abs(src - s.fps) > 1e-9:
        axis_angle, trans, positions, resampled = resample_generated(
            axis_angle, trans, positions, src, s.fps
        )
    try:
        done = postprocess_motion(
            axis_angle,
            trans,
            positions,
            s.fps,
            smooth_cutoff_hz=s.smooth_cutoff,
            smooth_order=s.smooth_order,
            repair_flips=s.repair_hip_flips,
            flip_threshold_deg=s.flip_threshold_deg,
        )
    except ValueError as exc:
        raise InputError(str(exc), item.path) from None
    flips = done.flips

    def f32(a: np.ndarray | None) -> np.ndarray | None:
        return None if a is None else np.ascontiguousarray(a, dtype=np.float32)

    return GeneratedRead(
        layout=motion.layout,
        source_frames=motion.n_frames,
        axis_angle=f32(done.axis_angle),
        trans=f32(done.trans),
        positions=f32(done.positions),
        resampled=resampled,
        flip_frames=np.zeros(0, np.int64) if flips is None else flips.frames,
        flip_angles_deg=np.zeros(0) if flips is None else flips.angles_deg,
        flip_runs=[] if flips is None else [[a, b] for a, b in flips.runs],
        flip_summary=None if flips is None else flips.summary(),
    )


@dataclass
class _Reference:
    """What the source takes from the reference store."""

    path: str
    version: str
    fingerprint: str
    fps: float
    motion_attrs: dict[str, Any]
    array_attrs: dict[str, dict[str, Any]]
    sequences: dict[str, dict[str, Any]]
    music: list[dict[str, Any]]
    splits: list[dict[str, Any]]

    @property
    def joints(self) -> int:
        return len(self.motion_attrs["skeleton"]["joints"])


def _open_reference(path: str | Path, version: str | None) -> _Reference:
    from dancedata.read.loader import open_store

    ref = open_store(path, version)
    attrs = ref.group_attrs("motion")
    skeleton = attrs.get("skeleton") or {}
    if not skeleton.get("joints"):
        raise InputError(
            "the reference store names no skeleton (its motion attrs have none: a music-only "
            "store?); give a store with motion",
            ref.path,
        )
    fps = attrs.get("fps")
    if not isinstance(fps, (int, float)) or not fps > 0:
        raise InputError(f"the reference store's frame rate {fps!r} is not positive", ref.path)
    array_attrs = {
        name: dict(ref.zarr(f"motion/{name}").attrs)
        for name in ("axis_angle", "trans", "positions")
        if ref.has_array(f"motion/{name}")
    }
    rows = {row["seq_id"]: row for row in ref.sequences.to_pylist()}
    music = ref.music.to_pylist() if ref.has_table("music") else []
    splits = ref.splits.to_pylist() if ref.has_table("splits") else []
    return _Reference(
        path=str(path),
        version=ref.version,
        fingerprint=str(ref.manifest.get("fingerprint")),
        fps=float(fps),
        motion_attrs=dict(attrs),
        array_attrs=array_attrs,
        sequences=rows,
        music=music,
        splits=splits,
    )


def _seq_id_of(name: str, known: dict[str, dict[str, Any]]) -> str | None:
    """The sequence id a file name names: ``<seq_id><suffix>``, or EDGE's
    ``<prefix>_<seq_id><suffix>`` when the whole stem is no sequence; None for other suffixes."""
    suffix = next((s for s in NAME_SUFFIXES if name.lower().endswith(s)), None)
    if suffix is None:
        return None
    stem = name[: -len(suffix)]
    if stem not in known and "_" in stem and stem.split("_", 1)[1] in known:
        return stem.split("_", 1)[1]
    return stem


def _check_file_size(path: Path, mode: int, max_frames: int) -> None:
    """Refuse a file larger than any accepted motion of at most ``max_frames`` frames can be
    (1024 values a frame of at most 16 bytes, plus 1 MiB of headers), before it is hashed."""
    size = path.stat().st_size
    most = max_frames * MAX_ROW_VALUES * 16 + (1 << 20)
    if size > most:
        raise InputError(
            f"{size} bytes, more than a motion of at most {max_frames} frames can hold "
            f"({most} bytes: twice the reference sequence's frames + 1200)",
            path,
        )


def _resolved(path: str | Path) -> Path | None:
    try:
        return Path(str(path)).resolve()  # (a backend's str is its path as given)
    except (OSError, RuntimeError):
        return None


@register_source("generated")
class GeneratedSource(Source):
    """A folder of generated motion as records shaped like the reference (module docstring)."""

    command = COMMAND

    def __init__(self, folder: str | Path, options: GeneratedIngestOptions) -> None:
        options.check()
        self.folder = Path(folder)
        self.options = options
        self.on_error = options.on_error
        self.kind: str | None = None  # "rotations" or "positions": fixed by the first record

    # -- before the version opens ----------------------------------------------------------
    def plan(self, store: str | Path, checksums: InputChecksums, skips: SkipPolicy) -> IngestPlan:
        if not self.folder.is_dir():
            raise InputError("no such folder of generated motion", self.folder)
        ref = self.ref = _open_reference(self.options.like, self.options.like_version)
        o = self.options
        if o.smooth_cutoff is not None and not o.smooth_cutoff < ref.fps / 2:
            raise InputError(
                f"--smooth-cutoff {o.smooth_cutoff} Hz must be below half the reference's "
                f"frame rate ({ref.fps / 2:g} Hz)"
            )
        self.settings = GeneratedSettings(
            fps=ref.fps,
            generated_fps=o.generated_fps,
            up_axis=o.up_axis,
            smooth_cutoff=o.smooth_cutoff,
            smooth_order=o.smooth_order,
            repair_hip_flips=o.repair_hip_flips,
            flip_threshold_deg=o.flip_threshold_deg,
        )
        try:
            entries = sorted(os.listdir(self.folder))
        except OSError as exc:
            raise InputError(f"cannot list the folder: {exc.strerror}", self.folder) from None
        self.ignored = 0
        claimed: dict[str, Path] = {}
        tasks: list[ReadTask] = []
        keys = [f"like {ref.version} {ref.fingerprint}"]
        for name in entries:
            path = self.folder / name
            seq_id = _seq_id_of(name, ref.sequences)
            if seq_id is None:
                self.ignored += 1
                continue
            try:
                mode = path.lstat().st_mode
                if stat.S_ISDIR(mode):
                    self.ignored += 1
                    continue
                if not stat.S_ISREG(mode):
                    raise InputError("not a regular file (links are not followed)", path)
                check_seq_id(seq_id, path)
                row = ref.sequences.get(seq_id)
                if row is None:
                    raise InputError(
                        f"no sequence {seq_id!r} in the reference store (version "
                        f"{ref.version}): files are named <seq_id>.npy|.npz|.pkl",
                        path,
                    )
                if seq_id in claimed:
                    raise InputError(
                        f"two files for sequence {seq_id} ({claimed[seq_id].name} and {name})",
                        path,
                    )
                limit = generated_frame_limit(int(row["n_frames"]), o.generated_fps, ref.fps)
                _check_file_size(path, mode, limit)
                sha = checksums.sha(path)  # (after the size check: hashing reads it all)
            except InputError as exc:
                skips.fail_or_skip(exc, path)
                continue
            claimed[seq_id] = path
            item = _FileItem(str(path), sha, seq_id, limit, self.settings)
            tasks.append(ReadTask(str(path), item))
            keys.append(f"generated {seq_id} {sha}")
        if not tasks and not skips.skipped:
            raise InputError(
                "no generated motion files (<seq_id>.npy|.npz|.pkl) in the folder", self.folder
            )
        mine, like = _resolved(store), _resolved(self.options.like)
        if mine is not None and mine == like:
            raise InputError(
                "--store is the reference store (--like): write the generated motion to "
                "another store",
                store,
            )
        return IngestPlan(
            config=self.config(),
            fingerprint_keys=keys,
            inputs=None,
            tasks=tasks,
            parse=read_generated,
            task_kind="generated",
            arrays=self._arrays,
            read_desc="read generated motion",
            sequences_desc="ingest generated sequences",
            workers=o.workers,
            wait_for_lock=o.wait_for_lock,
            empty_error=InputError("every generated file was skipped; nothing to ingest"),
        )

    def config(self) -> dict[str, Any]:
        o, ref = self.options, self.ref
        return {
            "like": {"store": ref.path, "version": ref.version, "fingerprint": ref.fingerprint},
            "fps": ref.fps,
            "skeleton": ref.motion_attrs["skeleton"].get("name"),
            "generated_fps": o.generated_fps,
            "resample": "decimation for an integer ratio, else SLERP of rotations and linear "
            "translation and positions (dancedata.compute.resample)",
            "generated_up_axis": o.up_axis,
            "fact225": "3x3 blocks projected on the nearest rotation (SVD, det +1)",
            "quat": "normalised, then axis-angle",
            "postprocess": postprocess_config(
                o.smooth_cutoff, o.smooth_order, o.repair_hip_flips, o.flip_threshold_deg
            ),
            "on_error": o.on_error,
        }

    # -- records ---------------------------------------------------------------------------
    def read(self, task: ReadTask, parsed: Callable[[], Any]) -> SequenceRecord:
        read: GeneratedRead = parsed()
        item: _FileItem = task.item
        ref = self.ref
        kind = "rotations" if read.axis_angle is not None else "positions"
        if self.kind is not None and kind != self.kind:
            raise InputError(
                f"holds {kind} ({read.layout}) but the first file accepted holds {self.kind}: "
                "one kind of motion per version",
                task.path,
            )
        array = read.axis_angle if read.axis_angle is not None else read.positions
        assert array is not None
        skeleton = ref.motion_attrs["skeleton"]
        if array.shape[1] != ref.joints:
            raise InputError(
                f"{read.layout} motion of {array.shape[1]} joints; the reference skeleton "
                f"{skeleton.get('name')!r} has {ref.joints}",
                task.path,
            )
        if read.n_frames < 1:
            raise InputError("no frames", task.path)
        self.kind = kind
        row = ref.sequences[item.seq_id]
        music_ids = {m["music_id"] for m in ref.music}
        music_id = row.get("music_id")
        arrays = (
            {"trans": read.trans, "axis_angle": read.axis_angle}
            if kind == "rotations"
            else {"positions": read.positions}
        )
        return SequenceRecord(
            seq_id=item.seq_id,
            source="generated",
            path=str(Path(task.path).resolve()),
            sha256=item.sha256,
            fps=ref.fps,
            n_frames=read.n_frames,
            arrays=arrays,  # type: ignore[arg-type]
            **{c: row.get(c) for c in SEQUENCE_COLUMNS},
            music_key=music_id if music_id in music_ids else None,
            music_id=music_id,
            bpm=row.get("bpm"),
            columns={
                "generated_layout": read.layout,
                "generated_frames": read.source_frames,
                **(
                    {"hip_flip_frames": len(read.flip_frames)}
                    if self.options.repair_hip_flips
                    else {}
                ),
            },
            item=read,
        )

    def _arrays(self, first: SequenceRecord) -> list[StoredArray]:
        """The arrays of the kind of motion the first file holds, with the reference's attrs."""
        joints = self.ref.joints
        attrs = self.ref.array_attrs

        def spec(name: str, row: tuple[int, ...], units: str) -> StoredArray:
            return StoredArray(name, row, np.float32, attrs=attrs.get(name) or {"units": units})

        if self.kind == "rotations":
            return [spec("trans", (3,), "m"), spec("axis_angle", (joints, 3), "rad")]
        return [spec("positions", (joints, 3), "m")]

    def finish(self, records: list[SequenceRecord], totals: IngestTotals) -> Finished:
        from dancedata.ingest.aist.inputs import used_music

        attrs = dict(self.ref.motion_attrs)
        attrs["source"] = "generated"
        # the reference's source Euler channels are not stored here (rotations: axis_angle)
        attrs.pop("euler_orders", None)
        attrs["generated_like"] = {"version": self.ref.version, "fingerprint": self.ref.fingerprint}
        rows = used_music(self.ref.music, {r.music_key for r in records if r.music_key})
        present = {r.seq_id for r in records}
        return Finished(
            music=MusicTable(rows, {row["music_id"]: row for row in rows}),
            counts=self._counts(records, totals, len(rows)),
            tables={"splits": [dict(s) for s in self.ref.splits if s.get("seq_id") in present]},
            attrs={"motion": attrs},
        )

    def _counts(
        self, records: list[SequenceRecord], totals: IngestTotals, music: int
    ) -> dict[str, Any]:
        layouts: dict[str, int] = {}
        for r in records:
            layouts[r.item.layout] = layouts.get(r.item.layout, 0) + 1
        counts: dict[str, Any] = {
            "sequences": totals.sequences,
            "frames": totals.frames,
            "music": music,
            "music_missing": sum(r.music_key is None for r in records),
            "layouts": layouts,
            "resampled": sum(r.item.resampled is not None for r in records),
            "ignored_files": self.ignored,
            "skipped": totals.skipped,
            **totals.read_counts,
        }
        if self.options.repair_hip_flips:
            per_sequence = {
                r.seq_id: {
                    "runs": r.item.flip_runs[:MAX_FLIP_RUNS_LISTED],
                    "n_runs": len(r.item.flip_runs),
                    "frames": int(len(r.item.flip_frames)),
                    "summary": r.item.flip_summary,
                }
                for r in records
            }
            counts["hip_flips"] = {
                "sequences_with_flips": sum(v["n_runs"] > 0 for v in per_sequence.values()),
                "runs": sum(v["n_runs"] for v in per_sequence.values()),
                "frames": sum(v["frames"] for v in per_sequence.values()),
                "per_sequence": per_sequence,
            }
        return counts


def ingest_generated(
    store: str | Path, folder: str | Path, options: GeneratedIngestOptions
) -> CommandResult:
    """Ingest the generated-motion files of ``folder`` into a new version of ``store``, shaped
    like the reference store ``options.like`` (module docstring)."""
    return ingest(store, GeneratedSource(folder, options))


def flip_lines(result: CommandResult) -> list[str]:
    """One line per sequence with repaired flips (for the console), or none."""
    flips = result.counts.get("hip_flips") if result.counts else None
    if not flips:
        return []
    lines = [
        f"hip flips: {flips['runs']} run(s), {flips['frames']} frame(s) turned back in "
        f"{flips['sequences_with_flips']} sequence(s)"
    ]
    for seq_id, info in flips["per_sequence"].items():
        if info["n_runs"]:
            lines.append(f"  {seq_id}: {info['summary']}")
    return lines
