"""``dancedata ingest video``: video-derived poses, aligned to each video's clock, into a new
store version.

Steps: inventory (:mod:`~dancedata.ingest.video_inputs`: which poses, CSV and music go with
each video) → checksums and fingerprint (same inputs and settings: nothing is written) → per
video, clock → poses → frame check → track → fill gaps → resample
(:mod:`~dancedata.ingest.video_poses`) and its music (:mod:`~dancedata.ingest.video_music`) →
one new version holding only these sequences (its parent is recorded, nothing is carried over).

Every input is read and checked before the version is opened, so a bad input leaves the store
exactly as it was. Stored arrays (docs/STORE.md, "Video-derived poses"):

* ``motion/pose2d`` (F, J, 3) float32: x, y in pixels (origin top-left, y down) and the
  detector's confidence; x, y NaN and confidence 0 where missing. J = 25 (BODY_25) or 18 (COCO).
* ``motion/pose2d_mask`` (F, J) uint8: 0 missing, 1 detected, 2 gap-filled.
* ``motion/positions`` (F, K, 3) float32 metres from ``--joints-csv``, NaN where missing, and
  ``motion/positions_mask`` (F, K) uint8 with the same codes.
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any

from dancedata._version import __version__
from dancedata.errors import InputError
from dancedata.ingest.locked import already_ingested, latest_version
from dancedata.ingest.run_state import IngestRun
from dancedata.ingest.video_inputs import (
    Checksums,
    VideoInputs,
    check_unique_stems,
    find_video_inputs,
    sequence_key,
    sequence_sha256,
)
from dancedata.ingest.video_music import MusicTrack, bpm_method, music_from_file
from dancedata.ingest.video_poses import MASK_CODES, PoseSettings, VideoPoses
from dancedata.ingest.video_read import VideoRead, VideoReadItem, read_video
from dancedata.progress import progress
from dancedata.store.arrays import FrameArrayWriter
from dancedata.store.checksums import fingerprint
from dancedata.store.command_result import CommandResult
from dancedata.store.contract import build_table
from dancedata.store.writer import VersionWriter, hold_store_lock

COMMAND = "ingest video"


@dataclass
class VideoIngestOptions:
    """Every setting of a video ingest (all but ``wait_for_lock`` are fingerprinted).

    Attributes:
        poses: ``--poses`` folder (see :mod:`dancedata.ingest.video_inputs` for the mapping).
        joints_csv: ``--joints-csv`` file or folder of 3-d joints.
        music: ``--music`` file or folder; None: each video's audio track.
        no_music: store no music at all (ignore audio tracks).
        bpm: tempo of the music in beats per minute; None: estimate it per track.
        genre: genre label of every sequence.
        up_axis: the up axis recorded in the motion attrs ("-y": image and camera frames).
        settings: the per-video pipeline settings.
        on_error: "fail" or "skip" (skip a bad video, or a malformed pose file as a missing
            frame, and record it in the manifest).
    """

    poses: Path | None = None
    joints_csv: Path | None = None
    music: Path | None = None
    no_music: bool = False
    bpm: float | None = None
    genre: str | None = None
    up_axis: str = "-y"
    settings: PoseSettings = field(default_factory=PoseSettings)
    on_error: str = "fail"
    wait_for_lock: bool = False

    def music_source(self) -> str:
        if self.no_music:
            return "none"
        return "file" if self.music is not None else "video_audio"

    def config(self) -> dict[str, Any]:
        return {
            "source": "video",
            **self.settings.config(),
            "inputs": {"poses": self.poses is not None, "joints_csv": self.joints_csv is not None},
            "music": self.music_source(),
            "audio_offset": 0,
            "bpm": self.bpm,
            "bpm_estimate": bpm_method() if self.bpm is None and not self.no_music else None,
            "genre": self.genre,
            "up_axis": self.up_axis,
            "on_error": self.on_error,
        }

    def check(self) -> None:
        if self.poses is None and self.joints_csv is None:
            raise InputError("give the poses: --poses DIR (OpenPose JSON) and/or --joints-csv")
        if self.no_music and self.music is not None:
            raise InputError("--music and --no-music exclude each other")
        if self.bpm is not None and not self.bpm > 0:
            raise InputError(f"--bpm must be positive, not {self.bpm}")
        if self.settings.fps is not None and not self.settings.fps > 0:
            raise InputError(f"--fps must be positive, not {self.settings.fps}")
        if self.settings.max_gap < 0:
            raise InputError(f"--max-gap must be 0 or more, not {self.settings.max_gap}")


# ----------------------------------------------------------------------------- reading


@dataclass(kw_only=True)
class _Run(IngestRun):
    """What one ingest gathers before writing."""

    options: VideoIngestOptions


@dataclass
class _Sequence:
    """One accepted video: its files, poses and music."""

    inputs: VideoInputs
    poses: VideoPoses
    music: MusicTrack | None


def read_items(
    found: list[VideoInputs], options: VideoIngestOptions, checksums: Checksums
) -> list[VideoReadItem]:
    """One :func:`~dancedata.ingest.video_read.read_video` item per video, in store order."""
    audio_track = not options.no_music and options.music is None
    return [
        VideoReadItem(
            inputs=inputs,
            settings=options.settings,
            skip_bad_files=options.on_error == "skip",
            audio_track=audio_track,
            video_sha256=checksums.sha(inputs.video) if audio_track else None,
            bpm=options.bpm,
        )
        for inputs in found
    ]


def music_files(
    found: list[VideoInputs], options: VideoIngestOptions, checksums: Checksums
) -> dict[str, MusicTrack | InputError]:
    """Each ``--music`` file described once (tempo estimated unless ``--bpm``), or the error
    describing it raised (raised again for each video it belongs to)."""
    tracks: dict[str, MusicTrack | InputError] = {}
    if options.no_music:
        return tracks
    for inputs in found:
        if inputs.music is None or str(inputs.music) in tracks:
            continue
        try:
            tracks[str(inputs.music)] = music_from_file(
                inputs.music, checksums.sha(inputs.music), options.bpm
            )
        except InputError as exc:
            tracks[str(inputs.music)] = exc
    return tracks


def sequence_of(
    inputs: VideoInputs, read: VideoRead, tracks: dict[str, MusicTrack | InputError]
) -> _Sequence:
    """A video's read with its music: the audio track read with it, or its ``--music`` file
    (InputError when that could not be described)."""
    music = read.audio
    if inputs.music is not None and str(inputs.music) in tracks:
        track = tracks[str(inputs.music)]
        if isinstance(track, InputError):
            raise track
        music = track
    return _Sequence(inputs, read.poses, music)


def check_consistent(first: _Sequence, seq: _Sequence) -> None:
    """Every sequence of one store shares the frame rate and skeletons."""
    a, b = first.poses, seq.poses
    video = seq.inputs.video
    if abs(a.fps - b.fps) > 1e-9:
        raise InputError(
            f"frame rate {b.fps:g} differs from {a.fps:g} of {first.inputs.video.name}; pass "
            "--fps to resample every video to one rate",
            video,
        )
    if (a.skeleton2d and a.skeleton2d.name) != (b.skeleton2d and b.skeleton2d.name):
        raise InputError(
            f"body model {b.skeleton2d.name if b.skeleton2d else None} differs from "
            f"{a.skeleton2d.name if a.skeleton2d else None} of {first.inputs.video.name}",
            seq.inputs.poses or video,
        )
    if a.skeleton3d != b.skeleton3d:
        raise InputError(
            f"the joints CSV's joints differ from those of {first.inputs.video.name}",
            seq.inputs.joints_csv or video,
        )


def _process(run: _Run, found: list[VideoInputs]) -> list[_Sequence]:
    opts = run.options
    tracks = music_files(found, opts, run)
    done: list[_Sequence] = []
    items = read_items(found, opts, run)
    for item in progress(items, "ingest videos", unit="video"):
        try:
            seq = sequence_of(item.inputs, read_video(item), tracks)
        except InputError as exc:
            run.fail_or_skip(exc, item.inputs.video)
            continue
        if done:
            check_consistent(done[0], seq)  # a setting problem: never skipped
        run.skipped += [{"path": p, "error": e} for p, e in seq.poses.bad_files]
        done.append(seq)
    if not done:
        raise InputError("every video was skipped; nothing to ingest")
    return done


# ----------------------------------------------------------------------------- tables


def music_rows(seqs: list[_Sequence], genre: str | None, fps: float) -> dict[str, dict]:
    """Music table rows keyed by file path (one per distinct file, feature frames packed from
    0 at ``fps``); ids made unique."""
    rows: dict[str, dict[str, Any]] = {}
    ids: set[str] = set()
    start = 0
    for seq in seqs:
        track = seq.music
        if track is None or str(track.path) in rows:
            continue
        row = track.row(genre, start, fps)
        if row["music_id"] in ids:
            row["music_id"] = f"{track.music_id}-{track.sha256[:8]}"
        ids.add(row["music_id"])
        rows[str(track.path)] = row
        start = row["frame_stop"]
    return rows


def video_columns(seq: _Sequence) -> dict[str, Any]:
    """The sequences table's video columns of one sequence (docs/STORE.md)."""
    poses, inputs = seq.poses, seq.inputs
    tracking = poses.report.get("tracking", {})
    return {
        "video_fps": poses.video_fps,
        "video_frames": poses.video_frames,
        "video_frames_used": poses.report["video_frames_used"],
        "drift_frames": poses.report["drift_frames"],
        "width": poses.width,
        "height": poses.height,
        "tracking_method": tracking.get("method"),
        "tracked_person": tracking.get("chosen"),
        "identity_switches": tracking.get("identity_switches"),
        "joints_filled": tracking.get("joints_filled"),
        "frames_filled": tracking.get("frames_filled"),
        "poses_path": None if inputs.poses is None else str(inputs.poses),
        "joints_csv_path": None if inputs.joints_csv is None else str(inputs.joints_csv),
    }


def _sequence_row(
    seq: _Sequence, music: dict[str, Any] | None, frame: int, run: _Run
) -> dict[str, Any]:
    poses, opts = seq.poses, run.options
    n = poses.n_frames
    music_frames = None if music is None else music["frame_stop"] - music["frame_start"]
    bpm = seq.music.bpm if seq.music is not None else opts.bpm
    return {
        "seq_id": seq.inputs.seq_id,
        "source": "video",
        "genre": opts.genre,
        "situation": None,
        "dancer": None,
        "music_id": None if music is None else music["music_id"],
        "choreo": None,
        "bpm": bpm,
        "fps": poses.fps,
        "n_frames": n,
        "frame_start": frame,
        "frame_stop": frame + n,
        "audio_offset": 0,
        "audio_frames": 0 if music_frames is None else min(n, music_frames),
        "audio_truncated_frames": 0 if music_frames is None else max(0, music_frames - n),
        "music_missing": music is None,
        "bpm_estimated": None if bpm is None else bool(seq.music and seq.music.bpm_estimated),
        **video_columns(seq),
        "path": str(seq.inputs.video),
        "sha256": sequence_sha256(run, seq.inputs),
    }


# ----------------------------------------------------------------------------- arrays


@dataclass(frozen=True)
class PoseArray:
    """One stored array of video poses: ``motion/<name>``, rows of ``row_shape`` as ``dtype``,
    taken from the :class:`VideoPoses` field ``field``."""

    name: str
    field: str
    row_shape: tuple[int, ...]
    dtype: str
    attrs: dict[str, Any]


def motion_attrs(first: VideoPoses, up_axis: str) -> dict[str, Any]:
    """The motion group's attrs, from the first sequence (every one shares them)."""
    skeleton = first.skeleton3d or (first.skeleton2d.to_dict() if first.skeleton2d else None)
    return {"fps": first.fps, "up_axis": up_axis, "skeleton": skeleton, "source": "video"}


def pose_arrays(first: VideoPoses) -> list[PoseArray]:
    """The stored arrays, in creation order, as the first sequence has them. Video 2-d poses
    are stored as motion/pose2d (one tracked dancer, one view), apart from AIST++'s multi-view
    keypoints2d."""
    arrays: list[PoseArray] = []
    if first.keypoints2d is not None:
        n_joints = first.keypoints2d.shape[1]
        attrs = {
            "units": "px",
            "channels": ["x", "y", "confidence"],
            "origin": "top-left, y down",
            "missing": "x, y NaN and confidence 0",
            "skeleton": first.skeleton2d.to_dict() if first.skeleton2d else None,
        }
        arrays.append(PoseArray("pose2d", "keypoints2d", (n_joints, 3), "float32", attrs))
        mask = {"of": "pose2d", "codes": MASK_CODES}
        arrays.append(PoseArray("pose2d_mask", "keypoints2d_mask", (n_joints,), "uint8", mask))
    if first.positions is not None:
        n_joints = first.positions.shape[1]
        attrs = {
            "units": "m",
            "source": "joints CSV (pose lifter)",
            "missing": "NaN",
            "skeleton": first.skeleton3d,
        }
        arrays.append(PoseArray("positions", "positions", (n_joints, 3), "float32", attrs))
        mask = {"of": "positions", "codes": MASK_CODES}
        arrays.append(PoseArray("positions_mask", "positions_mask", (n_joints,), "uint8", mask))
    return arrays


def _write_arrays(version: VersionWriter, seqs: list[_Sequence], up_axis: str) -> None:
    root = version.zarr_group()
    motion = root.require_group("motion")
    root.require_group("audio")
    first = seqs[0].poses
    motion.attrs.update(motion_attrs(first, up_axis))
    specs = pose_arrays(first)
    writers = [FrameArrayWriter(motion, a.name, a.row_shape, a.dtype, attrs=a.attrs) for a in specs]
    for seq in seqs:
        for spec, writer in zip(specs, writers, strict=True):
            writer.append(getattr(seq.poses, spec.field))
    for writer in writers:
        writer.close()


def video_counts(seqs: list[_Sequence], music: dict[str, dict], skipped: int) -> dict[str, Any]:
    """The manifest counts: totals, and per video its clock, drift, tracking and music."""
    videos: dict[str, Any] = {}
    for seq in seqs:
        report = dict(seq.poses.report)
        if seq.music is not None:
            report["music"] = {
                "path": str(seq.music.path),
                "source": seq.music.source,
                "bpm": seq.music.bpm,
                "bpm_estimated": seq.music.bpm_estimated,
            }
        videos[seq.inputs.seq_id] = report
    return {
        "sequences": len(seqs),
        "frames": sum(s.poses.n_frames for s in seqs),
        "music": len(music),
        "skipped": skipped,
        "bad_pose_files": sum(len(s.poses.bad_files) for s in seqs),
        "identity_switches": sum(
            s.poses.report.get("tracking", {}).get("identity_switches", 0) for s in seqs
        ),
        "drifted_sequences": sum(1 for s in seqs if s.poses.report["drift_frames"] != 0),
        "bpm_estimated": sum(1 for r in music.values() if r["bpm_estimated"]),
        "videos": videos,
    }


def ingest_video(
    store: str | Path, videos: list[str | Path], options: VideoIngestOptions
) -> CommandResult:
    """Ingest ``videos`` with their poses (``options``) into a new version of ``store``."""
    options.check()
    paths = [Path(v) for v in videos]
    if not paths:  # pose files only: no audio track, music only from --music
        if options.settings.fps is None:
            raise InputError(
                "no video, so the pose files carry no frame rate: give --fps (the video's frame "
                "rate the poses were estimated at)",
                options.poses or options.joints_csv,
            )
        options = replace(options, no_music=options.no_music or options.music is None)
    check_unique_stems(paths)
    run = _Run(on_error=options.on_error, options=options)
    opts = options
    found = find_video_inputs(paths, opts.poses, opts.joints_csv, opts.music, run)
    keys = [sequence_key(run, inputs) for inputs in progress(found, "checksums", unit="video")]
    config = options.config()
    fp = fingerprint(COMMAND, config, keys, __version__)
    ingested = already_ingested(store, fp)  # (asked again under the lock)
    if ingested is not None:
        return ingested

    seqs = _process(run, found)
    fps = seqs[0].poses.fps
    music = music_rows(seqs, options.genre, fps)
    rows: list[dict[str, Any]] = []
    frame = 0
    for seq in seqs:
        row = None if seq.music is None else music[str(seq.music.path)]
        rows.append(_sequence_row(seq, row, frame, run))
        frame += seq.poses.n_frames
    counts = video_counts(seqs, music, len(run.skipped))

    # No lost update: the parent is read once the lock is held (the items are entered in
    # order), and the result is looked for again under it (dancedata.ingest.locked).
    with (
        hold_store_lock(store, wait=options.wait_for_lock, create=True) as lock,
        VersionWriter(
            store,
            command=COMMAND,
            config=config,
            fingerprint=fp,
            inputs=list(run.described.values()),
            parent=latest_version(store),
            carry_over=False,
            wait_for_lock=options.wait_for_lock,
            stage="ingest",
            lock=lock,
        ) as version,
    ):
        ingested = already_ingested(store, fp)  # by a writer this one waited for
        if ingested is not None:
            return ingested
        for item in run.skipped:
            version.skip(item["path"], item["error"])
        _write_arrays(version, seqs, options.up_axis)
        version.write_table("sequences", build_table("sequences", rows))
        if music:
            version.write_table("music", build_table("music", list(music.values())))
        version.write_table("splits", build_table("splits", []))
        name = version.commit(counts=counts)
    return CommandResult(version=name, created=True, counts=counts, skipped=version.skipped)
