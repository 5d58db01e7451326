"""Kinematics of a parsed BVH clip: rotations, forward kinematics, export angles, resampling.

:mod:`dancedata.io.bvh` only parses and writes the file (hierarchy, channels, frame values and
the per-joint channel arrays); the operations on a clip live here (issue 15 item 3: formats
parse, operations compute), as plain functions of a :class:`~dancedata.io.bvh.BvhClip`.

Conventions: a channel list ``Zrotation Xrotation Yrotation`` means ``R = Rz @ Rx @ Ry``, i.e.
scipy intrinsic ``from_euler("ZXY", [z, x, y], degrees=True)``; lengths stay in the clip's
units (file units until :func:`~dancedata.io.bvh.scale_clip`), angles in degrees.
"""

from __future__ import annotations

import warnings

import numpy as np
from scipy.spatial.transform import Rotation

from dancedata.compute.euler_continuity import euler_continuous, euler_nearest
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
    return _euler_deg_to_rotmat(euler_degrees(clip), clip.skeleton.rotation_orders)


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
    rotmats = np.asarray(rotmats, dtype=np.float64)
    euler = _rotmat_to_euler_rad(rotmats, skeleton.rotation_orders)
    orders = skeleton.rotation_orders
    out = np.empty_like(euler)
    for order in sorted(set(orders)):
        idx = [j for j, o in enumerate(orders) if o == order]
        if reference_euler_deg is not None:
            ref = np.radians(np.asarray(reference_euler_deg, dtype=np.float64)[:, idx])
            out[:, idx] = euler_nearest(euler[:, idx], ref, order)
        else:
            out[:, idx] = euler_continuous(euler[:, idx], order)
    return clip_from_arrays(skeleton, frame_time_s, np.degrees(out), translations)


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


def _euler_deg_to_rotmat(euler_deg: np.ndarray, orders: tuple[str, ...]) -> np.ndarray:
    n_frames, n_joints = euler_deg.shape[:2]
    out = np.empty((n_frames, n_joints, 3, 3))
    for order in set(orders):
        idx = [j for j, o in enumerate(orders) if o == order]
        flat = euler_deg[:, idx].reshape(-1, 3)
        mats = Rotation.from_euler(order, flat, degrees=True).as_matrix()
        out[:, idx] = mats.reshape(n_frames, len(idx), 3, 3)
    return out


def _rotmat_to_euler_rad(rotmats: np.ndarray, orders: tuple[str, ...]) -> np.ndarray:
    n_frames, n_joints = rotmats.shape[:2]
    out = np.empty((n_frames, n_joints, 3))
    for order in set(orders):
        idx = [j for j, o in enumerate(orders) if o == order]
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", UserWarning)  # gimbal lock: scipy picks a split
            angles = Rotation.from_matrix(rotmats[:, idx].reshape(-1, 3, 3)).as_euler(order)
        out[:, idx] = angles.reshape(n_frames, len(idx), 3)
    return out
