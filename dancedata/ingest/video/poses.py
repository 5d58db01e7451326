"""One video's poses on the store's time base: clock, poses, frame check, track, fill, resample.

Pose frame i of a video belongs at ``i / video_fps`` seconds (the video's clock, read with
OpenCV), or with ``frame_times="decoded"`` at the presentation time OpenCV decodes for video frame
i (variable-frame-rate video; costs a full decode); stored frame k sits at ``k / fps`` with
``fps`` the target rate (default the video's).
Values are linearly interpolated by timestamp, confidences taken from the nearest frame
(:mod:`dancedata.compute.resample`).

Without a video (``inputs.has_video`` False) the pose files are the clock
(:func:`pose_clock`): ``fps`` must be given, pose frame i sits at ``i / fps`` and the frame count
is the pose files' own (OpenPose: highest file number + 1), so there is no drift to check.

Frame counts: the pose frames (OpenPose: highest file number + 1; CSV: rows or highest frame
number + 1) must equal the video's, else the video is refused unless ``allow_drift``. With drift
allowed, only the frames both have are kept (``min(pose, video)``) and the drift is reported.

Masks (uint8, per frame and joint): 0 missing, 1 detected (read from the input), 2 gap-filled
(interpolated across at most ``max_gap`` missing video frames, or resampled from such a value).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Literal

import numpy as np

from dancedata.compute.pose_tracking import fill_gaps, fill_tracked_gaps, track_openpose
from dancedata.compute.resample import ResampledPoses, check_frame_count, resample_by_time
from dancedata.errors import InputError
from dancedata.ingest.video.inputs import VideoInputs
from dancedata.io.joint_sets import LIFTER_SETS, normalise_name
from dancedata.io.joints_csv import read_joints_csv
from dancedata.io.openpose import BODY_25, COCO_18, Skeleton, read_openpose_folder
from dancedata.io.video_clock import VideoClock, read_video_clock

MASK_MISSING, MASK_DETECTED, MASK_FILLED = 0, 1, 2
MASK_CODES = {
    str(MASK_MISSING): "missing",
    str(MASK_DETECTED): "detected",
    str(MASK_FILLED): "gap-filled",
}
UNITS_TO_METRES = {"m": 1.0, "cm": 0.01, "mm": 0.001}
SKELETONS = {"body25": BODY_25, "coco18": COCO_18, **LIFTER_SETS}


@dataclass(frozen=True)
class PoseSettings:
    """Settings of the per-video pipeline (all change the data).

    Attributes:
        fps: target frames per second; None keeps each video's own rate.
        person: follow this person id / tracklet number instead of the default choice.
        select: default dancer rule, "area" (largest) or "frames" (most often seen).
        max_gap: longest run of missing video frames to interpolate (0: none).
        allow_drift: accept pose and video frame counts that differ (keep the overlap).
        units: units of the joints CSV, "m", "cm" or "mm" (stored in metres).
        skeleton: joint names of a headerless joints CSV: "body25" or "coco18".
        frame_base: the number of the video's first frame in a CSV frame column.
        frame_times: "nominal" (frame i at i / video_fps) or "decoded" (decoded timestamps).
    """

    fps: float | None = None
    person: int | None = None
    select: Literal["area", "frames"] = "area"
    max_gap: int = 3
    allow_drift: bool = False
    units: str = "m"
    skeleton: str | None = None
    frame_base: int = 0
    frame_times: Literal["nominal", "decoded"] = "nominal"

    def config(self) -> dict[str, Any]:
        return {
            "fps": self.fps,
            "person": self.person,
            "select": self.select,
            "max_gap_frames": self.max_gap,
            "allow_drift": self.allow_drift,
            "units": self.units,
            "csv_skeleton": self.skeleton,
            "csv_frame_base": self.frame_base,
            "frame_times": self.frame_times,
            "pose_frame_time": (
                "i / video_fps" if self.frame_times == "nominal" else "decoded timestamp of i"
            ),
            "resampling": "linear by timestamp; confidence from the nearest frame",
            "mask_codes": MASK_CODES,
        }


@dataclass
class VideoPoses:
    """One video's sequence, ready to store: arrays, JSON scalars and dataclasses only (no
    paths), so a read saved between runs of a resumable ingest rebuilds it exactly.

    Attributes:
        video_fps, video_frames: the clock's frame rate (frames per second) and frame count.
        width, height: frame size in pixels (None without a video).
        fps: the stored frame rate (frames per second).
        n_frames: stored frames.
        keypoints2d: (n_frames, J, 3) float32 x, y (pixels), confidence; x, y NaN and
            confidence 0 where missing; None without OpenPose input.
        keypoints2d_mask: (n_frames, J) uint8 mask codes (module docstring), or None.
        skeleton2d: the OpenPose body model, or None.
        positions: (n_frames, K, 3) float32 metres, NaN where missing; None without a CSV.
        positions_mask: (n_frames, K) uint8 mask codes, or None.
        skeleton3d: ``{"name", "joints", "parents"}`` of the CSV joints, or None.
        report: JSON-ready record of the clock, drift, tracking and gap filling.
        bad_files: (path, problem) of pose files skipped as missing frames.
    """

    video_fps: float
    video_frames: int
    width: int | None
    height: int | None
    fps: float
    n_frames: int
    keypoints2d: np.ndarray | None = None
    keypoints2d_mask: np.ndarray | None = None
    skeleton2d: Skeleton | None = None
    positions: np.ndarray | None = None
    positions_mask: np.ndarray | None = None
    skeleton3d: dict[str, Any] | None = None
    report: dict[str, Any] = field(default_factory=dict)
    bad_files: list[tuple[str, str]] = field(default_factory=list)


def skeleton_for_joints(names: tuple[str, ...]) -> tuple[dict[str, Any], list[int]]:
    """Match CSV joint names to a known joint set: BODY_25, COCO-18, H36M-17, SPIN-24 or HMR-19
    (case and every character but letters and digits ignored; ``io.joint_sets``).

    Returns the skeleton dict and, for each of its joints, the CSV column group to take. Names
    matching none give ``{"name": "custom", "joints": names, "parents": [-1, ...]}`` (no
    bone structure known) in CSV order.
    """
    normed = [normalise_name(n) for n in names]
    if len(set(normed)) == len(normed):
        for known in (BODY_25, COCO_18, *LIFTER_SETS.values()):
            spellings = known.spellings() if hasattr(known, "spellings") else [known.joints]
            for spelling in spellings:
                wanted = [normalise_name(j) for j in spelling]
                if sorted(wanted) == sorted(normed):
                    return known.to_dict(), [normed.index(j) for j in wanted]
    custom = {"name": "custom", "joints": list(names), "parents": [-1] * len(names)}
    return custom, list(range(len(names)))


def _mask_codes(mask: np.ndarray, filled: np.ndarray) -> np.ndarray:
    codes = np.where(mask, MASK_DETECTED, MASK_MISSING).astype(np.uint8)
    codes[mask & filled] = MASK_FILLED
    return codes


def _resample(
    values: np.ndarray,
    mask: np.ndarray,
    filled: np.ndarray,
    source_times: np.ndarray,
    target_times: np.ndarray,
    hold_until: float,
    conf: np.ndarray | None = None,
) -> tuple[ResampledPoses, np.ndarray]:
    """Resample values and carry the filled flag: a target value is filled when a filled
    source frame contributed to it."""
    out = resample_by_time(values, mask, source_times, target_times, conf, hold_until)
    flag = resample_by_time(
        filled.astype(np.float64)[..., None],
        mask,
        source_times,
        target_times,
        hold_until=hold_until,
    )
    filled_out = out.mask & (np.nan_to_num(flag.coords[..., 0]) > 0)
    return out, _mask_codes(out.mask, filled_out)


def _read_csv(path: Path, settings: PoseSettings):
    joints = None
    if settings.skeleton is not None:
        if settings.skeleton not in SKELETONS:
            raise InputError(
                f"unknown skeleton {settings.skeleton!r}; use one of {', '.join(SKELETONS)}"
            )
        joints = list(SKELETONS[settings.skeleton].joints)
    try:
        return read_joints_csv(
            path, joints=joints, index_column="auto", frame_base=settings.frame_base
        )
    except InputError as exc:
        if "no header row" in exc.problem:
            raise InputError(
                "no header row: pass --skeleton (one of "
                f"{', '.join(SKELETONS)}) to name its x, y, z columns",
                path,
            ) from None
        raise


def pose_clock(inputs: VideoInputs, settings: PoseSettings, n_frames: int) -> VideoClock:
    """The clock of pose files given without a video: ``n_frames`` frames (the highest
    OpenPose file number + 1, else the CSV's frames) at ``settings.fps`` (required), frame i at
    ``i / fps``, duration ``n_frames / fps``. The frame size is unknown (None)."""
    source = inputs.poses or inputs.joints_csv
    if settings.fps is None:
        raise InputError(
            "no video, so the pose files carry no frame rate: give --fps (the video's frame "
            "rate the poses were estimated at)",
            source,
        )
    if settings.frame_times == "decoded":
        raise InputError("--frame-times decoded needs the video file", source)
    return VideoClock(
        path=inputs.video,
        fps=float(settings.fps),
        n_frames=n_frames,
        duration_s=n_frames / float(settings.fps),
        width=None,  # type: ignore[arg-type]  # no image: size unknown
        height=None,  # type: ignore[arg-type]
        frame_count_source="OpenPose file numbers" if inputs.poses else "joints CSV frames",
        fps_source="--fps (no video)",
        property_frame_count=float("nan"),
        decoded_frame_count=None,
    )


def process_video(
    inputs: VideoInputs, settings: PoseSettings, skip_bad_files: bool = False
) -> VideoPoses:
    """Build one video's sequence (module docstring: the steps and rules).

    ``skip_bad_files`` turns a malformed pose file into a missing frame (recorded in
    ``bad_files``) instead of an error.

    Raises:
        InputError: naming the file, for an unreadable video, malformed poses, a frame-count
            mismatch without ``allow_drift``, or no one to track.
    """
    if settings.units not in UNITS_TO_METRES:
        raise InputError(f"unknown units {settings.units!r}; use m, cm or mm")
    if settings.frame_times not in ("nominal", "decoded"):
        raise InputError(f"unknown frame times {settings.frame_times!r}; use nominal or decoded")
    decoded = settings.frame_times == "decoded"
    bad: list[tuple[str, str]] = []
    frames = csv = None
    if inputs.poses is not None:
        frames = read_openpose_folder(
            inputs.poses,
            inputs.poses_prefix,
            on_bad_file=(lambda p, e: bad.append((str(p), e))) if skip_bad_files else None,
        )
    if inputs.joints_csv is not None:
        csv = _read_csv(inputs.joints_csv, settings)
    if inputs.has_video:
        clock = read_video_clock(inputs.video, verify="always" if decoded else "auto")
    else:
        clock = pose_clock(inputs, settings, frames.n_frames if frames else csv.n_frames)
    fps = settings.fps or clock.fps
    report: dict[str, Any] = {"video": clock.to_dict(), "fps": fps, "drift": {}}
    n_used = clock.n_frames

    tracked = None
    if frames is not None:
        drift = check_frame_count(
            frames.n_frames,
            clock.n_frames,
            clock.fps,
            settings.allow_drift,
            pose_path=str(inputs.poses),
            video_path=str(inputs.video),
        )
        report["drift"]["poses"] = drift.to_dict()
        report["pose_files_missing"] = int((~frames.present).sum())
        tracked = fill_tracked_gaps(
            track_openpose(frames, person=settings.person, select=settings.select),
            settings.max_gap,
        )
        report["tracking"] = tracked.report()
        n_used = min(n_used, frames.n_frames)

    if csv is not None:
        drift = check_frame_count(
            csv.n_frames,
            clock.n_frames,
            clock.fps,
            settings.allow_drift,
            pose_path=str(inputs.joints_csv),
            video_path=str(inputs.video),
        )
        report["drift"]["joints_csv"] = drift.to_dict()
        n_used = min(n_used, csv.n_frames)

    src_times = np.arange(n_used, dtype=np.float64) / clock.fps
    if decoded:
        stamps = clock.decoded_frame_times()[:n_used]
        report["decoded_times_max_deviation_ms"] = float(np.abs(stamps - src_times).max() * 1e3)
        src_times = stamps
    hold_until = float(src_times[-1]) + 1.0 / clock.fps  # the last frame shows for one period
    n_frames = int(np.ceil(hold_until * fps - 1e-9))  # every target time before hold_until
    report.update(
        {
            "frame_times": settings.frame_times,
            "video_frames_used": n_used,
            "frames": n_frames,
            "drift_frames": _worst(report["drift"]),
        }
    )
    target_times = np.arange(n_frames, dtype=np.float64) / fps
    result = VideoPoses(
        video_fps=clock.fps,
        video_frames=clock.n_frames,
        width=clock.width,
        height=clock.height,
        fps=fps,
        n_frames=n_frames,
        report=report,
        bad_files=bad,
    )

    if tracked is not None:
        out, codes = _resample(
            tracked.coords[:n_used],
            tracked.mask[:n_used],
            tracked.filled[:n_used],
            src_times,
            target_times,
            hold_until,
            conf=tracked.conf[:n_used],
        )
        result.keypoints2d = np.concatenate([out.coords, out.conf[..., None]], axis=-1)
        result.keypoints2d_mask = codes
        result.skeleton2d = frames.skeleton

    if csv is not None:
        skeleton, order = skeleton_for_joints(csv.joints)
        values = csv.positions[:n_used][:, order] * UNITS_TO_METRES[settings.units]
        known = np.isfinite(values).all(axis=-1)
        values, known, filled = fill_gaps(values, known, settings.max_gap)
        times = src_times
        if csv.times is not None:  # the lifter wrote its own timestamps: resample by them
            rows = np.flatnonzero(csv.present[:n_used])
            values, known, filled, times = values[rows], known[rows], filled[rows], csv.times[rows]
        out, codes = _resample(values, known, filled, times, target_times, hold_until)
        result.positions = out.coords
        result.positions_mask = codes
        result.skeleton3d = skeleton
        report["joints_csv"] = {
            "joints": len(skeleton["joints"]),
            "skeleton": skeleton["name"],
            "units": settings.units,
            "timestamps": csv.times is not None,
            "joints_filled": int(filled.sum()),
            "known_fraction": float(out.mask.mean()) if out.mask.size else 0.0,
        }
    report["bad_pose_files"] = len(bad)
    return result


def _worst(drifts: dict[str, dict[str, Any]]) -> int:
    """The drift (pose frames minus video frames) of largest size over the sources."""
    values = [d["drift_frames"] for d in drifts.values()]
    return max(values, key=abs) if values else 0
