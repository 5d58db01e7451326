"""One BVH file → the arrays a store holds: read, convert to metres, check the size, smooth,
resample, then derive the per-joint arrays.

Order of operations (each optional step recorded in the manifest config):

1. read (file units, degrees) and scale to metres (``--units``);
2. snap the frame time to the nominal rate (``.0083333`` s → 120 fps, see
   :attr:`~dancedata.io.bvh.BvhClip.nominal_fps`);
3. smooth (``--smooth-cutoff``, ``--smooth-order``): zero-phase Butterworth on sign-continuous
   quaternions of every joint's local rotation, at the file's rate, so that smoothing before
   decimation also acts as an anti-alias filter. Euler channels are then re-derived on the
   branch nearest the original curves (winding kept). Translations are not smoothed;
4. resample (``--fps``): exact decimation for an integer rate ratio, SLERP otherwise
   (:func:`~dancedata.ops.bvh_clip.resample_clip`);
5. arrays, all float64 here (the store keeps float32): ``euler`` (radians, each joint's own
   order), ``axis_angle``, ``trans`` (root position, metres), ``positions`` (FK, metres) and,
   for rigs with position channels on non-root joints, ``local_translations`` (each joint's
   per-frame translation from its parent, metres; its OFFSET where it has no channels).
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
from scipy.spatial.transform import Rotation

from dancedata.compute.bvh_units import PLAUSIBLE_SIZE_M, LengthUnit, check_rig_size, rig_size
from dancedata.compute.smoothing import smooth_quaternions
from dancedata.errors import InputError
from dancedata.io.bvh import (
    BvhClip,
    declared_frames,
    euler_degrees,
    euler_radians,
    local_translations,
    read_bvh,
    root_translation,
    scale_clip,
)
from dancedata.ops.bvh_clip import (
    clip_from_rotations,
    local_rotmats,
    resample_clip,
    world_positions,
)

__all__ = ["BvhMotion", "BvhSettings", "has_joint_translations", "process_bvh"]


@dataclass(frozen=True)
class BvhSettings:
    """Per-file processing settings (all change the data).

    Attributes:
        units: the files' length unit.
        fps: target frame rate in frames/s, or None to keep each file's nominal rate.
        smooth_cutoff_hz: Butterworth cut-off in Hz, or None for no smoothing.
        smooth_order: Butterworth order (the zero-phase filter doubles it).
        check_size: fail when the rig's size is implausible (see bvh_units).
        frames: "declared" (a MOTION block holding another number of rows than ``Frames:``
            declares is an error) or "present" (every row the block holds is a frame).
    """

    units: LengthUnit
    fps: float | None = None
    smooth_cutoff_hz: float | None = None
    smooth_order: int = 2
    check_size: bool = True
    frames: str = "declared"

    def config(self) -> dict[str, Any]:
        return {
            "units": self.units.name,
            "metres_per_unit": self.units.metres,
            "fps": self.fps,
            "resample": "exact decimation for integer rate ratios, else SLERP + linear",
            "smooth": (
                None
                if self.smooth_cutoff_hz is None
                else {
                    "filter": "butterworth low-pass, zero-phase (sosfiltfilt)",
                    "cutoff_hz": self.smooth_cutoff_hz,
                    "order": self.smooth_order,
                    "on": "sign-continuous local joint quaternions, at the file's rate, "
                    "before resampling",
                }
            ),
            "size_check_m": list(PLAUSIBLE_SIZE_M) if self.check_size else None,
            "frames": self.frames,
        }


@dataclass(frozen=True, eq=False)
class BvhMotion:
    """A processed BVH file (lengths in metres, angles in radians).

    Attributes:
        clip: the processed clip (metres, degrees), at ``fps``.
        fps: frame rate of the stored frames.
        source_fps: the file's nominal frame rate; source_frames: its frame count;
        source_frame_time_s: its Frame Time exactly as written.
        size_m: the rig's size (see :func:`~dancedata.compute.bvh_units.rig_size`).
        euler, axis_angle: (F, J, 3); trans: (F, 3); positions: (F, J, 3);
        local_translations: (F, J, 3) or None (see the module docstring).
        declared_frames: the count the file's ``Frames:`` line declares (``source_frames`` is
            the rows read: they differ only with ``frames="present"``).
    """

    clip: BvhClip
    fps: float
    source_fps: float
    source_frames: int
    source_frame_time_s: float
    size_m: float
    euler: np.ndarray
    axis_angle: np.ndarray
    trans: np.ndarray
    positions: np.ndarray
    local_translations: np.ndarray | None
    declared_frames: int | None = None

    @property
    def n_frames(self) -> int:
        return self.clip.n_frames


def has_joint_translations(clip: BvhClip) -> bool:
    """Some non-root joint has position channels."""
    return bool(clip.skeleton.has_position_channels[1:].any())


def smooth_clip(clip: BvhClip, cutoff_hz: float, order: int) -> BvhClip:
    """Low-pass every joint's local rotation (see the module docstring, step 3)."""
    n_frames, n_joints = clip.n_frames, clip.skeleton.n_joints
    xyzw = Rotation.from_matrix(local_rotmats(clip).reshape(-1, 3, 3)).as_quat()
    quat = xyzw.reshape(n_frames, n_joints, 4)[..., [3, 0, 1, 2]]
    smooth = smooth_quaternions(quat, clip.fps, cutoff_hz, order)
    rotmats = Rotation.from_quat(smooth[..., [1, 2, 3, 0]].reshape(-1, 4)).as_matrix()
    return clip_from_rotations(
        clip.skeleton,
        clip.frame_time_s,
        rotmats.reshape(n_frames, n_joints, 3, 3),
        local_translations(clip),
        reference_euler_deg=euler_degrees(clip),
    )


def process_bvh(path: str | Path, settings: BvhSettings) -> BvhMotion:
    """Read and process one BVH file; InputError names the file on any problem."""
    path = Path(path)
    present = settings.frames == "present"
    raw = read_bvh(path, rows_present=present)
    if raw.n_frames == 0:
        raise InputError("the file holds no frames", path)
    clip = scale_clip(raw, settings.units.metres)
    source_fps = clip.nominal_fps
    clip = BvhClip(clip.skeleton, 1.0 / source_fps, clip.values)
    if settings.smooth_cutoff_hz is not None and clip.n_frames > 1:
        try:
            clip = smooth_clip(clip, settings.smooth_cutoff_hz, settings.smooth_order)
        except ValueError as exc:
            raise InputError(
                f"--smooth-cutoff: {exc} (the file runs at {source_fps:g} fps)", path
            ) from None
    fps = source_fps
    if settings.fps is not None:
        clip = resample_clip(clip, settings.fps)
        fps = float(settings.fps)
    positions = world_positions(clip)
    size = rig_size(positions)
    if settings.check_size:
        check_rig_size(size, settings.units, path)
    rotmats = local_rotmats(clip)
    axis_angle = Rotation.from_matrix(rotmats.reshape(-1, 3, 3)).as_rotvec()
    return BvhMotion(
        clip=clip,
        fps=fps,
        source_fps=source_fps,
        source_frames=raw.n_frames,
        source_frame_time_s=raw.frame_time_s,
        size_m=size,
        euler=euler_radians(clip),
        axis_angle=axis_angle.reshape(clip.n_frames, clip.skeleton.n_joints, 3),
        trans=root_translation(clip),
        positions=positions,
        local_translations=local_translations(clip) if has_joint_translations(clip) else None,
        declared_frames=declared_frames(path) if present else raw.n_frames,
    )
