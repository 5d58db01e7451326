"""Rotation representations, vectorised over any leading shape (frames, joints, ...).

All angles are radians. Quaternions are stored scalar-first (w, x, y, z); scipy's are
scalar-last, so conversions go through :func:`scipy.spatial.transform.Rotation` with an explicit
reorder. Euler orders follow scipy: upper case is intrinsic, lower case extrinsic. The 6D layout
is Zhou et al. 2019: the first two *columns* of the rotation matrix, (r00, r10, r20, r01, r11, r21)
(``rot6d``); ``rot6d_rows`` is the first two *rows*, (r00, r01, r02, r10, r11, r12), the layout
of pytorch3d's ``matrix_to_rotation_6d`` and of the code built on it (EDGE). For the same R
the two differ (rows of R are the columns of Rᵀ): decoding one layout with the other's decoder
gives Rᵀ = R⁻¹, the inverse rotation.
"""

from __future__ import annotations

import numpy as np
from scipy.spatial.transform import Rotation

ROT6D_LAYOUT = "zhou2019-columns: [R[:,0], R[:,1]] = (r00, r10, r20, r01, r11, r21)"
ROT6D_ROWS_LAYOUT = (
    "pytorch3d-rows: [R[0,:], R[1,:]] = (r00, r01, r02, r10, r11, r12) "
    "(pytorch3d matrix_to_rotation_6d, EDGE)"
)
QUAT_ORDER = "wxyz"


def _flat(rotations: np.ndarray, tail: int) -> tuple[np.ndarray, tuple[int, ...]]:
    values = np.asarray(rotations, dtype=np.float64)
    lead = values.shape[: values.ndim - tail]
    return values.reshape((-1,) + values.shape[values.ndim - tail :]), lead


def axis_angle_to_rotmat(axis_angle: np.ndarray) -> np.ndarray:
    """(..., 3) rotation vectors (radians) → (..., 3, 3) rotation matrices."""
    flat, lead = _flat(axis_angle, 1)
    return Rotation.from_rotvec(flat).as_matrix().reshape(lead + (3, 3))


def rotmat_to_axis_angle(rotmat: np.ndarray) -> np.ndarray:
    """(..., 3, 3) rotation matrices → (..., 3) rotation vectors (radians, angle in [0, π])."""
    flat, lead = _flat(rotmat, 2)
    return Rotation.from_matrix(flat).as_rotvec().reshape(lead + (3,))


def axis_angle_to_quat(axis_angle: np.ndarray) -> np.ndarray:
    """(..., 3) rotation vectors → (..., 4) unit quaternions, wxyz."""
    flat, lead = _flat(axis_angle, 1)
    xyzw = Rotation.from_rotvec(flat).as_quat()
    return xyzw[:, [3, 0, 1, 2]].reshape(lead + (4,))


def quat_to_axis_angle(quat: np.ndarray) -> np.ndarray:
    """(..., 4) wxyz quaternions → (..., 3) rotation vectors."""
    flat, lead = _flat(quat, 1)
    return Rotation.from_quat(flat[:, [1, 2, 3, 0]]).as_rotvec().reshape(lead + (3,))


def quat_to_rotmat(quat: np.ndarray) -> np.ndarray:
    """(..., 4) wxyz quaternions → (..., 3, 3) rotation matrices."""
    flat, lead = _flat(quat, 1)
    return Rotation.from_quat(flat[:, [1, 2, 3, 0]]).as_matrix().reshape(lead + (3, 3))


def rotmat_to_quat(rotmat: np.ndarray) -> np.ndarray:
    """(..., 3, 3) rotation matrices → (..., 4) wxyz quaternions (w ≥ 0 before continuity)."""
    flat, lead = _flat(rotmat, 2)
    return Rotation.from_matrix(flat).as_quat()[:, [3, 0, 1, 2]].reshape(lead + (4,))


def axis_angle_to_euler(axis_angle: np.ndarray, order: str) -> np.ndarray:
    """(..., 3) rotation vectors → (..., 3) Euler angles in radians, in scipy ``order``."""
    flat, lead = _flat(axis_angle, 1)
    return Rotation.from_rotvec(flat).as_euler(order).reshape(lead + (3,))


def euler_to_axis_angle(euler: np.ndarray, order: str) -> np.ndarray:
    """(..., 3) Euler angles (radians, scipy ``order``) → (..., 3) rotation vectors."""
    flat, lead = _flat(euler, 1)
    return Rotation.from_euler(order, flat).as_rotvec().reshape(lead + (3,))


def euler_to_rotmat(euler: np.ndarray, order: str) -> np.ndarray:
    """(..., 3) Euler angles (radians, scipy ``order``) → (..., 3, 3) rotation matrices."""
    flat, lead = _flat(euler, 1)
    return Rotation.from_euler(order, flat).as_matrix().reshape(lead + (3, 3))


def rotmat_to_euler(rotmat: np.ndarray, order: str) -> np.ndarray:
    """(..., 3, 3) rotation matrices → (..., 3) Euler angles in radians (scipy ``order``)."""
    flat, lead = _flat(rotmat, 2)
    return Rotation.from_matrix(flat).as_euler(order).reshape(lead + (3,))


def rotmat_to_rot6d(rotmat: np.ndarray) -> np.ndarray:
    """(..., 3, 3) → (..., 6): the first two columns of R, column after column (Zhou 2019)."""
    rotmat = np.asarray(rotmat)
    return np.concatenate([rotmat[..., :, 0], rotmat[..., :, 1]], axis=-1)


def rot6d_to_rotmat(rot6d: np.ndarray) -> np.ndarray:
    """(..., 6) → (..., 3, 3) by Gram–Schmidt on the two stored columns (Zhou 2019)."""
    rot6d = np.asarray(rot6d, dtype=np.float64)
    a1, a2 = rot6d[..., :3], rot6d[..., 3:]
    b1 = a1 / np.linalg.norm(a1, axis=-1, keepdims=True)
    a2 = a2 - np.sum(b1 * a2, axis=-1, keepdims=True) * b1
    b2 = a2 / np.linalg.norm(a2, axis=-1, keepdims=True)
    b3 = np.cross(b1, b2)
    return np.stack([b1, b2, b3], axis=-1)


def rotmat_to_rot6d_rows(rotmat: np.ndarray) -> np.ndarray:
    """(..., 3, 3) → (..., 6): the first two rows of R, row after row (pytorch3d, EDGE)."""
    rotmat = np.asarray(rotmat)
    return rotmat[..., :2, :].reshape(rotmat.shape[:-2] + (6,))


def rot6d_rows_to_rotmat(rot6d: np.ndarray) -> np.ndarray:
    """(..., 6) → (..., 3, 3) by Gram–Schmidt on the two stored rows (pytorch3d's
    ``rotation_6d_to_matrix``: b1, b2 orthonormalised, b3 = b1 × b2, stacked as rows)."""
    return np.swapaxes(rot6d_to_rotmat(rot6d), -1, -2)


def quat_sign_continuous(quat: np.ndarray) -> np.ndarray:
    """Flip quaternion signs along axis 0 (time) so that consecutive frames have a
    non-negative dot product; q and −q are the same rotation, but filters and interpolation
    need a continuous path. Works per joint for (F, J, 4) or on (F, 4)."""
    quat = np.array(quat, dtype=np.float64, copy=True)
    if quat.shape[0] < 2:
        return quat
    dots = np.sum(quat[1:] * quat[:-1], axis=-1)
    flips = np.cumsum(dots < 0, axis=0) % 2 == 1
    quat[1:][flips] *= -1.0
    return quat
