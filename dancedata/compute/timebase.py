"""Put pose frames on a time base: resample to a target fps, and check them against the video.

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

from dataclasses import dataclass

import numpy as np

from dancedata.errors import InputError

_EPS = 1e-9


@dataclass(frozen=True)
class Resampled:
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
    return int(np.ceil(n_source * target_fps / source_fps - _EPS))


def resample_by_time(
    values: np.ndarray,
    mask: np.ndarray,
    source_times: np.ndarray,
    target_times: np.ndarray,
    conf: np.ndarray | None = None,
    hold_until: float | None = None,
) -> Resampled:
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
    i0 = np.searchsorted(src, tgt + _EPS, side="right") - 1
    inside = (i0 >= 0) & (tgt <= src[-1] + _EPS)
    held = np.zeros_like(inside)
    if hold_until is not None:
        held = (tgt > src[-1] + _EPS) & (tgt < hold_until - _EPS)
    i0c = np.clip(i0, 0, n - 1)
    i1c = np.clip(i0c + 1, 0, n - 1)
    span = np.where(i1c > i0c, src[i1c] - src[i0c], 1.0)
    w = np.where(i1c > i0c, (tgt - src[i0c]) / span, 0.0)
    w = np.where(np.abs(w) < _EPS, 0.0, w)
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
        nearest = np.where(w > 0.5 + _EPS, i1c, i0c)
        conf_out = np.where(ok, cf[nearest], 0.0)
    return Resampled(
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
) -> Resampled:
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
