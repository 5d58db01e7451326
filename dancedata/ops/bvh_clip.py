"""Operations on a parsed BVH clip: local rotations, forward kinematics, export, resampling.

:mod:`dancedata.io.bvh` only parses and writes the file (hierarchy, channels, frame values and
the per-joint channel arrays); the array maths is in :mod:`dancedata.compute` (Euler
conventions in :mod:`~dancedata.compute.bvh_kinematics`, FK in :mod:`~dancedata.compute.fk`,
resampling in :mod:`~dancedata.compute.resample`). This module joins the two for a
:class:`~dancedata.io.bvh.BvhClip` (issue 15 item 3: formats parse, operations compute).
Lengths stay in the clip's units (file units until :func:`~dancedata.io.bvh.scale_clip`),
angles in degrees.
"""

from __future__ import annotations

import numpy as np
from scipy.spatial.transform import Rotation

from dancedata.compute.bvh_kinematics import euler_from_rotmats, euler_to_rotmats
from dancedata.compute.fk import forward_kinematics
from dancedata.compute.resample import (
    decimation_step,
    resample_linear,
    resample_positions,
    resample_quaternions,
)
from dancedata.io.bvh import (
    BvhClip,
    BvhSkeleton,
    clip_from_arrays,
    euler_degrees,
    local_translations,
)

__all__ = ["clip_from_rotations", "local_rotmats", "resample_clip", "world_positions"]


def local_rotmats(clip: BvhClip) -> np.ndarray:
    """(F, J, 3, 3) local joint rotations, ``R = R_axis1 @ R_axis2 @ R_axis3``."""
    return euler_to_rotmats(euler_degrees(clip), clip.skeleton.rotation_orders)


def world_positions(clip: BvhClip) -> np.ndarray:
    """(F, J, 3) world joint positions by forward kinematics, file units."""
    trans = local_translations(clip)
    return forward_kinematics(
        clip.skeleton.parents, clip.skeleton.offsets, local_rotmats(clip), joint_translations=trans
    )


def clip_from_rotations(
    skeleton: BvhSkeleton,
    frame_time_s: float,
    rotmats: np.ndarray,
    translations: np.ndarray | None = None,
    reference_euler_deg: np.ndarray | None = None,
) -> BvhClip:
    """A clip from (F, J, 3, 3) local rotation matrices, e.g. for export from a store.

    Euler angles are taken in each joint's channel order. Of the equivalent angle triples, the
    one nearest ``reference_euler_deg`` (F, J, 3) is chosen when given, otherwise the curve is
    made continuous over time (no ±180° jumps, no branch flips), which is what smoothing and
    animation tools need. Rotations about axes a joint has no channel for are lost.
    """
    euler = euler_from_rotmats(rotmats, skeleton.rotation_orders, reference_euler_deg)
    return clip_from_arrays(skeleton, frame_time_s, euler, translations)


def resample_clip(clip: BvhClip, fps: float, rtol: float = 1e-3) -> BvhClip:
    """Resample a clip to ``fps`` (see :mod:`dancedata.compute.resample` for the frame count).

    An integer rate ratio k keeps every k-th frame bit for bit (frame time × k). Otherwise
    rotations are SLERPed and position channels interpolated linearly. Euler angles are then
    taken on the branch nearest the (unwrapped, linearly interpolated) source curves and
    written with the winding (multiple of 360°) of the nearest source frame, so an output frame
    that falls on a source frame gets that frame's channel values back.
    """
    k = decimation_step(clip.fps, fps, rtol)
    if k is not None:
        return BvhClip(clip.skeleton, clip.frame_time_s * k, clip.values[::k].copy())
    positions = resample_positions(clip.n_frames, clip.fps, fps, rtol)
    quat = Rotation.from_matrix(local_rotmats(clip).reshape(-1, 3, 3)).as_quat()
    quat = quat.reshape(clip.n_frames, clip.skeleton.n_joints, 4)[..., [3, 0, 1, 2]]
    new_quat = resample_quaternions(quat, positions)
    rotmats = Rotation.from_quat(new_quat[..., [1, 2, 3, 0]].reshape(-1, 4)).as_matrix()
    rotmats = rotmats.reshape(len(positions), clip.skeleton.n_joints, 3, 3)
    reference = np.degrees(
        resample_linear(np.unwrap(np.radians(euler_degrees(clip)), axis=0), positions)
    )
    translations = resample_linear(local_translations(clip), positions)
    out = clip_from_rotations(clip.skeleton, 1.0 / fps, rotmats, translations, reference)
    nearest = euler_degrees(clip)[np.rint(positions).astype(np.int64)]
    euler = euler_degrees(out)
    euler += 360.0 * np.rint((nearest - euler) / 360.0)
    return clip_from_arrays(clip.skeleton, 1.0 / fps, euler, translations)
