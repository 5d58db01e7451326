"""Pure conversions that put generated and ground-truth motion into the spaces the metrics read.

* FACT 225-d rows → SMPL axis-angle + translation, projecting each 3×3 block onto the nearest
  rotation (SVD, det +1) first, as mint ``recover_to_axis_angles`` / ``get_closest_rotmat`` do
  (a network's rows are not exact rotations).
* axis-angle + translation → ``thesis_euler_75`` rows (the MSE's default space) in the store's
  Euler order, and ``fact_motion_225`` rows.
"""

from __future__ import annotations

import numpy as np

from dancedata.compute.rotations import (
    axis_angle_to_euler,
    axis_angle_to_rotmat,
    rotmat_to_axis_angle,
)

__all__ = [
    "closest_rotmat",
    "euler75_rows",
    "fact225_rows",
    "fact_rows_to_smpl",
    "resample_generated",
    "z_up_to_y_up",
]


def closest_rotmat(matrices: np.ndarray) -> np.ndarray:
    """(..., 3, 3) → the nearest rotation matrices in the Frobenius norm: U·diag(1, 1, det)·Vᵀ
    from the SVD M = U S Vᵀ."""
    u, _, vh = np.linalg.svd(np.asarray(matrices, dtype=np.float64))
    det = np.linalg.det(u @ vh)
    fix = np.ones(det.shape + (3,))
    fix[..., 2] = np.sign(det)
    return (u * fix[..., None, :]) @ vh


def fact_rows_to_smpl(rows: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(F, 225) FACT rows → ((F, 24, 3) axis-angle rad, (F, 3) translation m)."""
    rows = np.asarray(rows, dtype=np.float64)
    rotmat = closest_rotmat(rows[:, 9:225].reshape(-1, 24, 3, 3))
    return rotmat_to_axis_angle(rotmat), rows[:, 6:9].copy()


def euler75_rows(euler: np.ndarray, trans: np.ndarray) -> np.ndarray:
    """(F, 24, 3) Euler angles + (F, 3) translation → (F, 75) rows (translation first)."""
    euler = np.asarray(euler, dtype=np.float64)
    return np.concatenate([np.asarray(trans, dtype=np.float64), euler.reshape(len(euler), -1)], 1)


def fact225_rows(axis_angle: np.ndarray, trans: np.ndarray) -> np.ndarray:
    """(F, 24, 3) axis-angle + (F, 3) translation → (F, 225) FACT rows (6 zeros first)."""
    rotmat = axis_angle_to_rotmat(axis_angle).reshape(len(axis_angle), -1)
    return np.concatenate([np.zeros((len(rotmat), 6)), np.asarray(trans, np.float64), rotmat], 1)


def axis_angle_euler(axis_angle: np.ndarray, order: str) -> np.ndarray:
    """(F, 24, 3) axis-angle → (F, 24, 3) Euler angles (rad, scipy ``order``, principal)."""
    return axis_angle_to_euler(axis_angle, order)


# The rotation that takes z-up coordinates back to y-up: −90° about x, (x, y, z) → (x, z, −y).
# EDGE turns AIST++ y-up data to z-up with +90° about x (its dance_dataset.py); this undoes it.
_Z_TO_Y = np.array([[1.0, 0.0, 0.0], [0.0, 0.0, 1.0], [0.0, -1.0, 0.0]])


def z_up_to_y_up(
    axis_angle: np.ndarray | None, trans: np.ndarray | None, positions: np.ndarray | None
) -> tuple[np.ndarray | None, np.ndarray | None, np.ndarray | None]:
    """Motion in a z-up world → the same motion in SMPL's y-up world: points and the root
    translation rotated by −90° about x, the root joint's rotation premultiplied by it (the
    other joints' rotations are relative to their parents and do not change)."""
    if axis_angle is not None:
        axis_angle = np.array(axis_angle, dtype=np.float64)
        root = _Z_TO_Y @ axis_angle_to_rotmat(axis_angle[:, 0])
        axis_angle[:, 0] = rotmat_to_axis_angle(root)
    if trans is not None:
        trans = np.asarray(trans, dtype=np.float64) @ _Z_TO_Y.T
    if positions is not None:
        positions = np.asarray(positions, dtype=np.float64) @ _Z_TO_Y.T
    return axis_angle, trans, positions


def resample_generated(
    axis_angle: np.ndarray | None,
    trans: np.ndarray | None,
    positions: np.ndarray | None,
    src_fps: float,
    dst_fps: float,
) -> tuple[np.ndarray | None, np.ndarray | None, np.ndarray | None, str]:
    """Generated motion at ``src_fps`` → ``dst_fps`` (:mod:`dancedata.compute.resample`: exact
    decimation for an integer ratio, else SLERP of rotations and linear translations and
    positions). Returns the arrays and the method used."""
    from dancedata.compute.resample import resample_linear, resample_motion, resample_positions
    from dancedata.compute.rotations import axis_angle_to_quat, quat_to_axis_angle

    n = len(axis_angle) if axis_angle is not None else len(positions)  # type: ignore[arg-type]
    where = resample_positions(n, src_fps, dst_fps)
    method = "slerp"
    if axis_angle is not None:
        moved = resample_motion(axis_angle_to_quat(axis_angle), trans, src_fps, dst_fps)
        axis_angle, trans, method = quat_to_axis_angle(moved.quat), moved.translations, moved.method
    if positions is not None:
        positions = resample_linear(positions, where)
    return axis_angle, trans, positions, method
