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

__all__ = ["closest_rotmat", "euler75_rows", "fact225_rows", "fact_rows_to_smpl"]


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
