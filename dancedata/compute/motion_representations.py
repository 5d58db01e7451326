"""Every rotation representation of a block of frames, from axis-angle, in one pass.

Pure: arrays in, arrays out. Works on any (F, J, 3) block; quaternion sign continuity over time
is handled per sequence by the caller, which knows where sequences start and stop.
"""

from __future__ import annotations

import numpy as np

from dancedata.compute.rotation_kernels import (
    rotation_representations,
    rotations_from_axis_angle,
)
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
    attrs: dict[str, dict[str, object]] = {
        "rotmat": {"units": "1"},
        "euler": {"order": euler_order, "units": "rad"},
        "quat": {"quat_order": "wxyz", "sign": "continuous over time within each sequence"},
        "rot6d": {"rot6d_layout": ROT6D_LAYOUT},
        "rot6d_rows": {"rot6d_layout": ROT6D_ROWS_LAYOUT},
    }
    return attrs[name]


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
    axis_angle: np.ndarray,
    names: tuple[str, ...] | list[str],
    euler_order: EulerOrder,
    *,
    dtype: type | None = None,
    bounds: np.ndarray | None = None,
) -> dict[str, np.ndarray]:
    """(F, J, 3) axis-angle (radians) → the requested representations, float64.

    Quaternions come out with w ≥ 0 per frame; make them continuous with
    :func:`continue_quat_signs`. With ``dtype`` (float32 for the stores), every array is
    written in that dtype by the compiled pass itself (the float64 numbers rounded once, as
    ``astype`` would), and with ``bounds`` (S, 2) the quaternions are sign-continuous within
    each [start, stop) of the (F, J, 3) block, in the same pass
    (:func:`dancedata.compute.rotation_kernels.rotation_representations`).
    """
    # One compiled pass (compute.rotation_kernels: scipy's formulas, per rotation) gives the
    # quaternions, matrices and Euler angles; the 6D layouts are slices of the matrices.
    values = np.asarray(axis_angle)
    if values.dtype not in (np.float32, np.float64):
        values = values.astype(np.float64)
    unknown = [n for n in names if n not in KNOWN_REPRESENTATIONS]
    if unknown:
        raise ValueError(f"unknown representation {unknown[0]!r}; known: {KNOWN_REPRESENTATIONS}")
    if dtype is not None or bounds is not None:
        if values.ndim != 3:
            raise ValueError(f"need axis-angle (F, J, 3) with dtype or bounds, got {values.shape}")
        return rotation_representations(
            values, names, euler_order, dtype=dtype or np.float64, bounds=bounds
        )
    lead = values.shape[:-1]
    flat = values.reshape(-1, 1, 3) if values.ndim != 3 else values
    wanted = set(names)
    computed = rotations_from_axis_angle(
        flat,
        quat="quat" in wanted,
        rotmat=bool({"rotmat", "rot6d", "rot6d_rows"} & wanted),
        euler_order=euler_order if "euler" in wanted else None,
    )
    out: dict[str, np.ndarray] = {}
    for name in names:
        if name == "rotmat":
            out[name] = computed["rotmat"].reshape(lead + (3, 3))
        elif name == "euler":
            out[name] = computed["euler"].reshape(lead + (3,))
        elif name == "quat":
            out[name] = computed["quat"].reshape(lead + (4,))
        elif name == "rot6d":
            out[name] = rotmat_to_rot6d(computed["rotmat"]).reshape(lead + (6,))
        else:
            out[name] = rotmat_to_rot6d_rows(computed["rotmat"]).reshape(lead + (6,))
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
