"""From one video's read to what ``ingest video`` stores: its music, the checks every sequence
of one store must pass, its table columns, the stored arrays and the manifest counts.

Pure functions over :class:`VideoSequence` (a video's files, poses and music); the source
(:class:`~dancedata.ingest.video.VideoSource`) hands them to the ingest engine.
"""

from __future__ import annotations

from dataclasses import dataclass, replace
from typing import Any

import numpy as np

from dancedata.errors import InputError
from dancedata.ingest.source import InputChecksums, SettingsConflict, StoredArray
from dancedata.ingest.video.inputs import VideoInputs
from dancedata.ingest.video.music import MusicTrack, music_from_file
from dancedata.ingest.video.poses import MASK_CODES, VideoPoses
from dancedata.ingest.video.read import VideoRead

# Stored array name → field of VideoPoses. Video 2-d poses are stored as motion/pose2d (one
# tracked dancer, one view), apart from AIST++'s multi-view keypoints2d.
POSE_FIELDS = {
    "pose2d": "keypoints2d",
    "pose2d_mask": "keypoints2d_mask",
    "positions": "positions",
    "positions_mask": "positions_mask",
}


@dataclass
class VideoSequence:
    """One accepted video: its files, poses and music."""

    inputs: VideoInputs
    poses: VideoPoses
    music: MusicTrack | None

    def arrays(self) -> dict[str, np.ndarray]:
        """The stored arrays it has, by name (motion/<name>)."""
        found = {name: getattr(self.poses, f) for name, f in POSE_FIELDS.items()}
        return {name: value for name, value in found.items() if value is not None}

    def without_arrays(self) -> VideoSequence:
        """The same sequence holding no arrays (kept for the tables once they are written)."""
        return replace(self, poses=replace(self.poses, **dict.fromkeys(POSE_FIELDS.values())))


# ----------------------------------------------------------------------------- music


def music_files(
    found: list[VideoInputs], bpm: float | None, checksums: InputChecksums
) -> dict[str, MusicTrack | InputError]:
    """Each ``--music`` file described once (tempo estimated unless ``bpm``), keyed by path,
    or the error describing it raised (raised again for each video it belongs to)."""
    tracks: dict[str, MusicTrack | InputError] = {}
    for inputs in found:
        if inputs.music is None or str(inputs.music) in tracks:
            continue
        try:
            tracks[str(inputs.music)] = music_from_file(
                inputs.music, checksums.sha(inputs.music), bpm
            )
        except InputError as exc:
            tracks[str(inputs.music)] = exc
    return tracks


def sequence_of(
    inputs: VideoInputs, read: VideoRead, tracks: dict[str, MusicTrack | InputError]
) -> VideoSequence:
    """A video's read with its music: the audio track read with it, or its ``--music`` file
    (InputError when that could not be described)."""
    music = read.audio
    if inputs.music is not None and str(inputs.music) in tracks:
        track = tracks[str(inputs.music)]
        if isinstance(track, InputError):
            raise track
        music = track
    return VideoSequence(inputs, read.poses, music)


def music_rows(seqs: list[VideoSequence], genre: str | None, fps: float) -> dict[str, dict]:
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


# ----------------------------------------------------------------------------- checks


def check_consistent(first: VideoSequence, seq: VideoSequence) -> None:
    """Every sequence of one store shares the frame rate and skeletons: otherwise a
    SettingsConflict naming the file and the first video (never skipped: a setting problem)."""
    a, b = first.poses, seq.poses
    video = seq.inputs.video
    if abs(a.fps - b.fps) > 1e-9:
        raise SettingsConflict(
            f"frame rate {b.fps:g} differs from {a.fps:g} of {first.inputs.video.name}; pass "
            "--fps to resample every video to one rate",
            video,
        )
    if (a.skeleton2d and a.skeleton2d.name) != (b.skeleton2d and b.skeleton2d.name):
        raise SettingsConflict(
            f"body model {b.skeleton2d.name if b.skeleton2d else None} differs from "
            f"{a.skeleton2d.name if a.skeleton2d else None} of {first.inputs.video.name}",
            seq.inputs.poses or video,
        )
    if a.skeleton3d != b.skeleton3d:
        raise SettingsConflict(
            f"the joints CSV's joints differ from those of {first.inputs.video.name}",
            seq.inputs.joints_csv or video,
        )


# ----------------------------------------------------------------------------- tables


def video_columns(seq: VideoSequence) -> dict[str, Any]:
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


def video_counts(seqs: list[VideoSequence], music: dict[str, dict], skipped: int) -> dict[str, Any]:
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


# ----------------------------------------------------------------------------- arrays


def motion_attrs(first: VideoPoses, up_axis: str) -> dict[str, Any]:
    """The motion group's attrs, from the first sequence (every one shares them)."""
    skeleton = first.skeleton3d or (first.skeleton2d.to_dict() if first.skeleton2d else None)
    return {"fps": first.fps, "up_axis": up_axis, "skeleton": skeleton, "source": "video"}


def pose_arrays(first: VideoPoses) -> list[StoredArray]:
    """The stored arrays, in creation order, as the first sequence has them."""
    arrays: list[StoredArray] = []
    if first.keypoints2d is not None:
        n_joints = first.keypoints2d.shape[1]
        attrs = {
            "units": "px",
            "channels": ["x", "y", "confidence"],
            "origin": "top-left, y down",
            "missing": "x, y NaN and confidence 0",
            "skeleton": first.skeleton2d.to_dict() if first.skeleton2d else None,
        }
        arrays.append(StoredArray("pose2d", (n_joints, 3), "float32", attrs=attrs))
        mask = {"of": "pose2d", "codes": MASK_CODES}
        arrays.append(StoredArray("pose2d_mask", (n_joints,), "uint8", attrs=mask))
    if first.positions is not None:
        n_joints = first.positions.shape[1]
        attrs = {
            "units": "m",
            "source": "joints CSV (pose lifter)",
            "missing": "NaN",
            "skeleton": first.skeleton3d,
        }
        arrays.append(StoredArray("positions", (n_joints, 3), "float32", attrs=attrs))
        mask = {"of": "positions", "codes": MASK_CODES}
        arrays.append(StoredArray("positions_mask", (n_joints,), "uint8", attrs=mask))
    return arrays
