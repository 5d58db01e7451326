"""BVH rotation conventions as plain array functions: Euler channels <-> rotation matrices.

A BVH channel list ``Zrotation Xrotation Yrotation`` means ``R = Rz @ Rx @ Ry``, i.e. scipy
intrinsic ``from_euler("ZXY", [z, x, y], degrees=True)``; each joint has its own order string.
These functions take and return arrays only (angles in degrees unless named ``_rad``), so they
import nothing of dancedata but compute/ (issue 15 item 3: formats parse, operations compute);
the clip-level operations built on them are in :mod:`dancedata.ops.bvh_clip`.
"""

from __future__ import annotations

import warnings

import numpy as np
from scipy.spatial.transform import Rotation

from dancedata.compute.euler_continuity import euler_continuous, euler_nearest

__all__ = ["euler_from_rotmats", "euler_to_rotmats", "rotmats_to_euler_rad"]


def euler_to_rotmats(euler_deg: np.ndarray, orders: tuple[str, ...]) -> np.ndarray:
    """(F, J, 3, 3) rotation matrices from (F, J, 3) Euler angles in degrees, joint j's
    angles in the intrinsic order ``orders[j]`` (e.g. "ZXY")."""
    n_frames, n_joints = euler_deg.shape[:2]
    out = np.empty((n_frames, n_joints, 3, 3))
    for order in set(orders):
        idx = [j for j, o in enumerate(orders) if o == order]
        flat = euler_deg[:, idx].reshape(-1, 3)
        mats = Rotation.from_euler(order, flat, degrees=True).as_matrix()
        out[:, idx] = mats.reshape(n_frames, len(idx), 3, 3)
    return out


def rotmats_to_euler_rad(rotmats: np.ndarray, orders: tuple[str, ...]) -> np.ndarray:
    """(F, J, 3) principal-branch Euler angles in radians of (F, J, 3, 3) rotation matrices,
    joint j in the intrinsic order ``orders[j]``; at gimbal lock scipy's split is kept."""
    n_frames, n_joints = rotmats.shape[:2]
    out = np.empty((n_frames, n_joints, 3))
    for order in set(orders):
        idx = [j for j, o in enumerate(orders) if o == order]
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", UserWarning)  # gimbal lock: scipy picks a split
            angles = Rotation.from_matrix(rotmats[:, idx].reshape(-1, 3, 3)).as_euler(order)
        out[:, idx] = angles.reshape(n_frames, len(idx), 3)
    return out


def euler_from_rotmats(
    rotmats: np.ndarray,
    orders: tuple[str, ...],
    reference_euler_deg: np.ndarray | None = None,
) -> np.ndarray:
    """(F, J, 3) Euler angles in degrees of (F, J, 3, 3) rotations, for writing channels.

    Of the equivalent angle triples, the one nearest ``reference_euler_deg`` (F, J, 3) is chosen
    when given, otherwise the curve is made continuous over time (no ±180° jumps, no branch
    flips), which is what smoothing and animation tools need."""
    rotmats = np.asarray(rotmats, dtype=np.float64)
    euler = rotmats_to_euler_rad(rotmats, orders)
    out = np.empty_like(euler)
    for order in sorted(set(orders)):
        idx = [j for j, o in enumerate(orders) if o == order]
        if reference_euler_deg is not None:
            ref = np.radians(np.asarray(reference_euler_deg, dtype=np.float64)[:, idx])
            out[:, idx] = euler_nearest(euler[:, idx], ref, order)
        else:
            out[:, idx] = euler_continuous(euler[:, idx], order)
    return np.degrees(out)
