"""Resampling frames to another rate: motion by frame position, pose frames by time.

One module for both resamplers of the package, each named by what it keeps exact:

* **motion** (:func:`resample_motion`, recorded as ``method`` ``"decimate"`` or ``"slerp"``):
  rotations and translations of a complete clip (BVH, SMPL, generated motion), by source frame
  position. See "Motion" below.
* **pose frames** (:func:`resample_poses`, :func:`resample_by_time`): 2-d or 3-d keypoints with a
  per-joint mask and confidence taken at a video's frame times, linear between known
  neighbours, never bridging a gap. See "Pose frames on a time base" below. The check of a pose
  frame count against its video (:func:`check_frame_count`) is here too: it decides which time
  base the poses are resampled from.

Motion
------

Output frame ``i`` sits at time ``i / dst_fps`` seconds, i.e. at source frame position
``i * src_fps / dst_fps``; only times inside the source clip are produced, so

    n_out = floor((n_in - 1) * dst_fps / src_fps) + 1        (0 when n_in is 0).

When ``src_fps / dst_fps`` is an integer ``k`` (within ``rtol``, because BVH files print the
frame time with few digits: ``.0083333`` s is 120.0005 fps), the motion is decimated exactly:
frames 0, k, 2k, ... are copied bit for bit and ``n_out = floor((n_in - 1) / k) + 1``. Otherwise
rotations are interpolated by SLERP between the two neighbouring source frames (quaternions,
``wxyz``) and translations linearly.

Pose frames on a time base
--------------------------

Pose frame i of a video at ``video_fps`` frames per second belongs at time ``i / video_fps``
seconds (frame i is shown from that instant). Target frame k of the output sits at
``k / target_fps``. Pure functions: arrays in, arrays out.

Resampling rules:

* coordinates: linear interpolation between the two source frames around the target time; the
  result is known only when both neighbours are known (a target time that falls exactly on a
  source frame needs only that frame). Missing neighbours give NaN and ``mask`` False — gaps are
  never bridged here (use :func:`dancedata.compute.pose_tracking.fill_gaps` first for that).
* confidences: the nearest source frame (ties to the earlier one); set to 0 where the output
  is missing, so ``conf > 0`` implies ``mask``.
* target times after the last source frame but before the end of its frame interval
  (``n_src / video_fps``) hold the last frame's value; nothing is extrapolated beyond that.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from dancedata.errors import InputError

__all__ = [
    "Drift",
    "ResampledMotion",
    "ResampledPoses",
    "check_frame_count",
    "decimation_step",
    "resample_by_time",
    "resample_linear",
    "resample_motion",
    "resample_poses",
    "resample_positions",
    "resample_quaternions",
    "resampled_frame_count",
    "slerp",
    "target_frame_count",
]

# Output times landing within this many source frames of a source frame count as on it.
_ON_FRAME = 1e-9


def decimation_step(src_fps: float, dst_fps: float, rtol: float = 1e-3) -> int | None:
    """The integer ``k`` with ``src_fps / dst_fps ≈ k`` (relative tolerance ``rtol``), else None.
    ``k = 1`` means the rates are equal."""
    if not (src_fps > 0 and dst_fps > 0):
        raise ValueError(f"frame rates must be positive, got {src_fps} and {dst_fps}")
    ratio = src_fps / dst_fps
    k = round(ratio)
    return k if k >= 1 and abs(ratio - k) <= rtol * ratio else None


def resampled_frame_count(n_frames: int, src_fps: float, dst_fps: float, rtol: float = 1e-3) -> int:
    """Number of output frames (see the module docstring for the formula)."""
    if n_frames <= 0:
        return 0
    k = decimation_step(src_fps, dst_fps, rtol)
    if k is not None:
        return (n_frames - 1) // k + 1
    return math.floor((n_frames - 1) * dst_fps / src_fps + _ON_FRAME) + 1


def resample_positions(
    n_frames: int, src_fps: float, dst_fps: float, rtol: float = 1e-3
) -> np.ndarray:
    """(n_out,) float positions of the output frames on the source frame axis."""
    n_out = resampled_frame_count(n_frames, src_fps, dst_fps, rtol)
    k = decimation_step(src_fps, dst_fps, rtol)
    if k is not None:
        return np.arange(n_out, dtype=np.float64) * k
    return np.minimum(np.arange(n_out) * (src_fps / dst_fps), n_frames - 1.0)


def _neighbours(positions: np.ndarray, n_frames: int) -> tuple[np.ndarray, np.ndarray]:
    """Left source index and fraction in [0, 1] for each position."""
    left = np.floor(positions + _ON_FRAME).astype(np.int64)
    left = np.clip(left, 0, max(n_frames - 2, 0))
    frac = np.clip(positions - left, 0.0, 1.0)
    frac[np.abs(frac) < _ON_FRAME] = 0.0
    return left, frac


def slerp(q0: np.ndarray, q1: np.ndarray, t: np.ndarray) -> np.ndarray:
    """Spherical linear interpolation of unit quaternions (..., 4) by ``t`` (broadcast to the
    leading shape), along the shorter arc. Nearly equal inputs fall back to normalised lerp."""
    q0 = np.asarray(q0, dtype=np.float64)
    q1 = np.asarray(q1, dtype=np.float64)
    t = np.asarray(t, dtype=np.float64)[..., None]
    dot = np.sum(q0 * q1, axis=-1, keepdims=True)
    q1 = np.where(dot < 0, -q1, q1)
    dot = np.clip(np.abs(dot), 0.0, 1.0)
    omega = np.arccos(dot)
    sin_omega = np.sin(omega)
    small = sin_omega < 1e-9
    safe = np.where(small, 1.0, sin_omega)
    w0 = np.where(small, 1.0 - t, np.sin((1.0 - t) * omega) / safe)
    w1 = np.where(small, t, np.sin(t * omega) / safe)
    out = w0 * q0 + w1 * q1
    return out / np.linalg.norm(out, axis=-1, keepdims=True)


def resample_quaternions(quat: np.ndarray, positions: np.ndarray) -> np.ndarray:
    """SLERP (F, ..., 4) quaternions at float source-frame ``positions`` → (N, ..., 4)."""
    quat = np.asarray(quat, dtype=np.float64)
    left, frac = _neighbours(np.asarray(positions, dtype=np.float64), quat.shape[0])
    right = np.minimum(left + 1, quat.shape[0] - 1)
    t = frac.reshape((-1,) + (1,) * (quat.ndim - 2))
    t = np.broadcast_to(t, (len(left),) + quat.shape[1:-1])
    out = slerp(quat[left], quat[right], t)
    exact = frac == 0.0
    out[exact] = quat[left[exact]]
    return out


def resample_linear(values: np.ndarray, positions: np.ndarray) -> np.ndarray:
    """Linear interpolation of (F, ...) values at float source-frame ``positions``."""
    values = np.asarray(values, dtype=np.float64)
    left, frac = _neighbours(np.asarray(positions, dtype=np.float64), values.shape[0])
    right = np.minimum(left + 1, values.shape[0] - 1)
    t = frac.reshape((-1,) + (1,) * (values.ndim - 1))
    out = values[left] * (1.0 - t) + values[right] * t
    exact = frac == 0.0
    out[exact] = values[left[exact]]
    return out


@dataclass(frozen=True)
class ResampledMotion:
    """Result of :func:`resample_motion`.

    Attributes:
        quat: (N, J, 4) wxyz rotations at the new rate.
        translations: resampled translations (N, ...), or None.
        source_positions: (N,) position of each output frame on the source frame axis.
        method: ``"decimate"`` (exact copies of every k-th frame) or ``"slerp"``.
        step: k when decimating, else None.
    """

    quat: np.ndarray
    translations: np.ndarray | None
    source_positions: np.ndarray
    method: str
    step: int | None


def resample_motion(
    quat: np.ndarray,
    translations: np.ndarray | None,
    src_fps: float,
    dst_fps: float,
    rtol: float = 1e-3,
) -> ResampledMotion:
    """Resample rotations (F, J, 4) wxyz and optional translations (F, ...) from ``src_fps`` to
    ``dst_fps``: exact decimation for an integer rate ratio, SLERP + linear otherwise."""
    quat = np.asarray(quat, dtype=np.float64)
    n_frames = quat.shape[0]
    if translations is not None:
        translations = np.asarray(translations, dtype=np.float64)
        if translations.shape[0] != n_frames:
            raise ValueError("quat and translations must have the same number of frames")
    positions = resample_positions(n_frames, src_fps, dst_fps, rtol)
    k = decimation_step(src_fps, dst_fps, rtol)
    if k is not None:
        return ResampledMotion(
            quat=quat[::k].copy(),
            translations=None if translations is None else translations[::k].copy(),
            source_positions=positions,
            method="decimate",
            step=k,
        )
    return ResampledMotion(
        quat=resample_quaternions(quat, positions),
        translations=None if translations is None else resample_linear(translations, positions),
        source_positions=positions,
        method="slerp",
        step=None,
    )


# Pose frames on a time base (see the module docstring).

# Target times within this many seconds of a source frame's time count as on it.
_ON_TIME = 1e-9


@dataclass(frozen=True)
class ResampledPoses:
    """Pose frames on the target time base.

    Attributes:
        coords: (T, J, D) float32 values (pixels or metres), NaN where unknown.
        conf: (T, J) float32 confidences (nearest source frame), 0 where unknown.
        mask: (T, J) bool, True where ``coords`` is known.
        times: (T,) float64 target times in seconds, ``k / target_fps``.
        source_position: (T,) float64 fractional source frame each value was taken from (the
            last frame for held times, NaN outside the source span).
    """

    coords: np.ndarray
    conf: np.ndarray
    mask: np.ndarray
    times: np.ndarray
    source_position: np.ndarray


@dataclass(frozen=True)
class Drift:
    """Pose frames minus video frames: ``frames`` (int) and ``seconds`` at the video fps."""

    pose_frames: int
    video_frames: int
    fps: float

    @property
    def frames(self) -> int:
        return self.pose_frames - self.video_frames

    @property
    def seconds(self) -> float:
        return self.frames / self.fps

    def to_dict(self) -> dict:
        return {
            "pose_frames": self.pose_frames,
            "video_frames": self.video_frames,
            "fps": self.fps,
            "drift_frames": self.frames,
            "drift_s": self.seconds,
        }


def target_frame_count(n_source: int, source_fps: float, target_fps: float) -> int:
    """Target frames whose time lies inside the source span ``[0, n_source / source_fps)``."""
    if n_source <= 0:
        return 0
    return int(np.ceil(n_source * target_fps / source_fps - _ON_TIME))


def resample_by_time(
    values: np.ndarray,
    mask: np.ndarray,
    source_times: np.ndarray,
    target_times: np.ndarray,
    conf: np.ndarray | None = None,
    hold_until: float | None = None,
) -> ResampledPoses:
    """Resample (N, J, D) ``values`` known where ``mask`` (N, J) from ``source_times`` (N,,
    strictly increasing seconds) to ``target_times`` (T,) by the module's rules.

    ``hold_until`` (seconds): target times in (last source time, hold_until) take the last
    frame; default: no hold. Target times outside the span are unknown (NaN).
    """
    vals = np.asarray(values, dtype=np.float64)
    known = np.asarray(mask, dtype=bool) & np.isfinite(vals).all(axis=-1)
    src = np.asarray(source_times, dtype=np.float64)
    tgt = np.asarray(target_times, dtype=np.float64)
    n = src.shape[0]
    if vals.shape[0] != n or known.shape != vals.shape[:2]:
        raise ValueError("values, mask and source_times disagree on the frame count")
    if n == 0:
        raise ValueError("no source frames")
    if n > 1 and not (np.diff(src) > 0).all():
        raise ValueError("source_times must be strictly increasing")
    cf = None if conf is None else np.asarray(conf, dtype=np.float64)

    # Index of the source frame at or before each target time, and the weight of the next one.
    i0 = np.searchsorted(src, tgt + _ON_TIME, side="right") - 1
    inside = (i0 >= 0) & (tgt <= src[-1] + _ON_TIME)
    held = np.zeros_like(inside)
    if hold_until is not None:
        held = (tgt > src[-1] + _ON_TIME) & (tgt < hold_until - _ON_TIME)
    i0c = np.clip(i0, 0, n - 1)
    i1c = np.clip(i0c + 1, 0, n - 1)
    span = np.where(i1c > i0c, src[i1c] - src[i0c], 1.0)
    w = np.where(i1c > i0c, (tgt - src[i0c]) / span, 0.0)
    w = np.where(np.abs(w) < _ON_TIME, 0.0, w)
    w = np.where(held, 0.0, np.clip(w, 0.0, 1.0))
    on_frame = w == 0.0

    v0, v1 = vals[i0c], vals[i1c]
    k0, k1 = known[i0c], known[i1c]
    ok = (inside | held)[:, None] & k0 & (on_frame[:, None] | k1)
    out = (1.0 - w)[:, None, None] * v0 + w[:, None, None] * np.where(k1[..., None], v1, 0.0)
    out = np.where(ok[..., None], out, np.nan)

    position = np.where(inside | held, i0c + w, np.nan)
    if cf is None:
        conf_out = ok.astype(np.float64)
    else:
        nearest = np.where(w > 0.5 + _ON_TIME, i1c, i0c)
        conf_out = np.where(ok, cf[nearest], 0.0)
    return ResampledPoses(
        coords=out.astype(np.float32),
        conf=conf_out.astype(np.float32),
        mask=ok,
        times=tgt,
        source_position=position,
    )


def resample_poses(
    coords: np.ndarray,
    mask: np.ndarray,
    video_fps: float,
    target_fps: float,
    conf: np.ndarray | None = None,
    n_target: int | None = None,
) -> ResampledPoses:
    """Resample pose frames taken at ``video_fps`` (frame i at ``i / video_fps`` s) to
    ``target_fps`` (frame k at ``k / target_fps`` s).

    Args:
        coords: (F, J, D) pixels or metres; mask (F, J) True where known; conf (F, J) optional.
        n_target: number of output frames; default :func:`target_frame_count`, i.e. every
            target time before the end of the last source frame's interval.
    """
    if not (video_fps > 0 and target_fps > 0):
        raise ValueError(f"frame rates must be positive (video {video_fps}, target {target_fps})")
    n_src = np.asarray(coords).shape[0]
    if n_target is None:
        n_target = target_frame_count(n_src, video_fps, target_fps)
    src_times = np.arange(n_src, dtype=np.float64) / video_fps
    tgt_times = np.arange(n_target, dtype=np.float64) / target_fps
    return resample_by_time(
        coords, mask, src_times, tgt_times, conf=conf, hold_until=n_src / video_fps
    )


def check_frame_count(
    pose_frames: int,
    video_frames: int,
    video_fps: float,
    allow_drift: bool = False,
    tolerance: int = 0,
    pose_path: str | None = None,
    video_path: str | None = None,
) -> Drift:
    """Compare the number of pose frames with the video's; returns the :class:`Drift`.

    A difference larger than ``tolerance`` frames raises :class:`InputError` naming both inputs,
    unless ``allow_drift`` is True, in which case the drift is returned for the manifest.
    """
    drift = Drift(int(pose_frames), int(video_frames), float(video_fps))
    if abs(drift.frames) > tolerance and not allow_drift:
        poses = f" ({pose_path})" if pose_path else ""
        raise InputError(
            f"{pose_frames} pose frames{poses} but {video_frames} video frames: drift "
            f"{drift.frames:+d} frames ({drift.seconds:+.3f} s at {video_fps:g} fps); check that "
            "the poses come from this video, or allow the drift (--allow-drift) to record it",
            video_path,
        )
    return drift
