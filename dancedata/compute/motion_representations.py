"""Every rotation representation of a block of frames, from axis-angle, in one pass.

Pure: arrays in, arrays out. Works on any (F, J, 3) block; quaternion sign continuity over time
is handled per sequence by the caller, which knows where sequences start and stop.
"""

from __future__ import annotations

import numpy as np
from scipy.spatial.transform import Rotation

from dancedata.compute.rotations import (
    ROT6D_LAYOUT,
    ROT6D_ROWS_LAYOUT,
    quat_sign_continuous,
    rotmat_to_euler,
    rotmat_to_rot6d,
    rotmat_to_rot6d_rows,
)

REPRESENTATIONS: tuple[str, ...] = ("rotmat", "euler", "quat", "rot6d")
# Offered on request (featurize --representations ...,rot6d_rows), not computed by default.
OPTIONAL_REPRESENTATIONS: tuple[str, ...] = ("rot6d_rows",)
KNOWN_REPRESENTATIONS: tuple[str, ...] = REPRESENTATIONS + OPTIONAL_REPRESENTATIONS


EulerOrder = str | list[str]


def representation_attrs(name: str, euler_order: EulerOrder) -> dict[str, object]:
    """The attrs the contract requires on each stored representation."""
    return {
        "rotmat": {"units": "1"},
        "euler": {"order": euler_order, "units": "rad"},
        "quat": {"quat_order": "wxyz", "sign": "continuous over time within each sequence"},
        "rot6d": {"rot6d_layout": ROT6D_LAYOUT},
        "rot6d_rows": {"rot6d_layout": ROT6D_ROWS_LAYOUT},
    }[name]


def row_shape(name: str, n_joints: int) -> tuple[int, ...]:
    return {
        "rotmat": (n_joints, 3, 3),
        "euler": (n_joints, 3),
        "quat": (n_joints, 4),
        "rot6d": (n_joints, 6),
        "rot6d_rows": (n_joints, 6),
    }[name]


def euler_per_joint(rotmat: np.ndarray, euler_order: EulerOrder) -> np.ndarray:
    """(F, J, 3, 3) → (F, J, 3) Euler angles in radians; ``euler_order`` is one scipy order for
    every joint or a list with each joint's own order (BVH rigs mix them)."""
    if isinstance(euler_order, str):
        return rotmat_to_euler(rotmat, euler_order)
    if len(euler_order) != rotmat.shape[1]:
        raise ValueError(f"{len(euler_order)} Euler orders for {rotmat.shape[1]} joints")
    out = np.empty(rotmat.shape[:2] + (3,))
    for order in set(euler_order):
        joints = [j for j, o in enumerate(euler_order) if o == order]
        out[:, joints] = rotmat_to_euler(rotmat[:, joints], order)
    return out


def representations_from_axis_angle(
    axis_angle: np.ndarray, names: tuple[str, ...] | list[str], euler_order: EulerOrder
) -> dict[str, np.ndarray]:
    """(F, J, 3) axis-angle (radians) → the requested representations, float64.

    Quaternions come out with w ≥ 0 per frame; make them continuous with
    :func:`continue_quat_signs`.
    """
    # One scipy Rotation serves every output: building it from a matrix again (from_matrix
    # re-orthogonalises) costs about three times the rest together.
    values = np.asarray(axis_angle, dtype=np.float64)
    lead = values.shape[:-1]
    rotation = Rotation.from_rotvec(values.reshape(-1, 3))
    per_joint_orders = not isinstance(euler_order, str)
    rotmat = None
    if {"rotmat", "rot6d", "rot6d_rows"} & set(names) or ("euler" in names and per_joint_orders):
        rotmat = rotation.as_matrix().reshape(lead + (3, 3))
    out: dict[str, np.ndarray] = {}
    for name in names:
        if name == "rotmat":
            out[name] = rotmat
        elif name == "euler":
            out[name] = (
                euler_per_joint(rotmat, euler_order)
                if per_joint_orders
                else rotation.as_euler(euler_order).reshape(lead + (3,))
            )
        elif name == "quat":
            out[name] = rotation.as_quat(canonical=True)[:, [3, 0, 1, 2]].reshape(lead + (4,))
        elif name == "rot6d":
            out[name] = rotmat_to_rot6d(rotmat)
        elif name == "rot6d_rows":
            out[name] = rotmat_to_rot6d_rows(rotmat)
        else:
            raise ValueError(f"unknown representation {name!r}; known: {KNOWN_REPRESENTATIONS}")
    return out


def continue_quat_signs(quat: np.ndarray, previous: np.ndarray | None) -> np.ndarray:
    """Make (F, J, 4) quaternions sign-continuous over time, continuing from ``previous``
    (the (J, 4) last frame of the same sequence) when the block continues a sequence, else
    starting from the block's first frame as it is."""
    if previous is None:
        return quat_sign_continuous(quat)
    joined = quat_sign_continuous(np.concatenate([previous[None], quat], axis=0))
    # quat_sign_continuous never flips frame 0, so `previous` keeps its sign.
    return joined[1:]
