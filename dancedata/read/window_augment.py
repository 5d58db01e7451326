"""Mirror and yaw augmentation of a window's rows: every stored array transformed as it must be.

A window is (L, D) float32 rows whose columns are the arrays of a view spec side by side, each
flattened from its row shape (:class:`dancedata.read.window_fit.ColumnPart`). The exact rules come
from :mod:`dancedata.compute.augment` (a reflection M = I − 2 e eᵀ across the sagittal plane maps
a local rotation R to M R M; a yaw Y about the up axis through the origin pre-multiplies the root
rotation and rotates world vectors):

* local rotations (``rotmat``, ``quat``, ``rot6d``, ``rot6d_rows``, ``axis_angle``, ``euler``):
  mirror swaps left/right joints and flips the sign of the entries M R M flips (entry (i, j) of R
  by sᵢsⱼ, s = diag M; the rotation-vector, quaternion-vector and Euler components about the
  lateral axis kept, the other two negated; each exact, so mirroring twice is the identity bit
  for bit); yaw pre-multiplies the root joint's rotation by Y;
* ``trans`` and world vectors per joint (``positions``, ``keypoints3d``, ``velocity``,
  ``acceleration``, ``jerk``): mirror swaps joints and negates the lateral coordinate; yaw
  rotates each vector by Y;
* angular velocity, acceleration and jerk (rotation vectors in the parent's frame): mirrored as
  rotation vectors; yaw rotates the root joint's (its parent frame is the world);
* joint-local offsets (``local_translations``, ``ik_rest_offsets``): mirror as vectors, yaw none;
* per-joint scalars (Laban efforts, masks, IK residuals): mirror swaps joints, yaw none;
* scalars summed over joints (weight effort, the ``*_sum`` arrays, motion beats) and every
  audio array: unchanged by both.

Anything else (2-D keypoints, per-sequence kinetic features, unknown arrays) is refused by
:func:`check_augmentable` with the array's name: an augmentation that cannot be exact is not
applied silently.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.spatial.transform import Rotation

from dancedata.compute.rotations import (
    axis_angle_to_rotmat,
    euler_to_rotmat,
    rot6d_rows_to_rotmat,
    rotmat_to_axis_angle,
    rotmat_to_euler,
    rotmat_to_rot6d_rows,
)
from dancedata.errors import InputError
from dancedata.read.window_fit import ColumnPart

__all__ = [
    "Mirror",
    "Rig",
    "Yaw",
    "check_augmentable",
    "mirror_rows",
    "yaw_rows",
]

ROTATIONS = ("rotmat", "quat", "rot6d", "rot6d_rows", "axis_angle", "euler")
WORLD_VECTORS = ("positions", "keypoints3d", "keypoints3d_optim", "velocity", "acceleration")
WORLD_VECTORS += ("jerk",)
ANGULAR = ("angular_velocity", "angular_acceleration", "angular_jerk")
LOCAL_VECTORS = ("local_translations", "ik_rest_offsets")
JOINT_SCALARS = ("laban_time", "laban_space", "laban_flow", "positions_mask", "ik_residual")
JOINT_SCALARS += ("ik_solved",)
INVARIANT = ("weight_effort", "laban_time_sum", "laban_space_sum", "laban_flow_sum")
INVARIANT += ("angular_acceleration_sum", "angular_jerk_sum")
INVARIANT += ("motion_beats_mint", "motion_beats_bailando")


@dataclass(frozen=True)
class Mirror:
    """Left/right mirror with probability ``p`` per item, across the plane normal to
    ``lateral_axis`` (0 = x: SMPL/AIST++ and CMU BVH rigs)."""

    p: float = 0.5
    lateral_axis: int = 0


@dataclass(frozen=True)
class Yaw:
    """A turn about the vertical axis by an angle uniform in [−max_deg, max_deg] degrees per
    item; ``up_axis`` None takes the store's (its motion ``up_axis`` attribute)."""

    max_deg: float = 180.0
    up_axis: int | None = None


@dataclass(frozen=True)
class Rig:
    """What the rules need of the store: left/right twin of each joint, the root joint, the
    up axis (0, 1, 2) and the Euler order of each joint (for ``motion/euler``)."""

    pairs: np.ndarray | None  # (J,) twin index; None when the joint names do not pair
    root: int
    up_axis: int
    euler_orders: tuple[str, ...] = ()
    pair_problem: str = ""


def _category(part: ColumnPart) -> str:
    if part.name == "zeros6" or part.name.startswith("audio/"):
        return "invariant"
    array = part.name.split("/", 1)[1]
    if array == "trans":
        return "trans"
    for category, names in (
        ("rotation", ROTATIONS),
        ("world", WORLD_VECTORS),
        ("angular", ANGULAR),
        ("local", LOCAL_VECTORS),
        ("joint_scalar", JOINT_SCALARS),
        ("invariant", INVARIANT),
    ):
        if array in names:
            return category
    return "unknown"


def check_augmentable(plan: list[ColumnPart], op: Mirror | Yaw, rig: Rig) -> None:
    """InputError naming the first part ``op`` cannot transform exactly (see the module)."""
    what = "mirror" if isinstance(op, Mirror) else "yaw"
    for part in plan:
        category = _category(part)
        if category == "unknown":
            raise InputError(
                f"{what} augmentation has no exact rule for {part.name} (rules exist for local "
                "rotations, trans, world and joint-local vectors, angular velocity and its "
                "derivatives, per-joint and summed scalars, audio); leave it out of the spec"
            )
        joints = part.shape[0] if part.shape else 0
        if isinstance(op, Mirror) and category not in ("invariant", "trans"):
            if rig.pairs is None:
                raise InputError(f"mirror augmentation: {rig.pair_problem}")
            if joints != len(rig.pairs):
                raise InputError(
                    f"mirror augmentation: {part.name} has {joints} joints, the rig "
                    f"{len(rig.pairs)}: its left/right pairs are unknown"
                )
        if part.name == "motion/euler" and len(rig.euler_orders) != joints:
            raise InputError("augmenting motion/euler needs its per-joint Euler orders")
        if isinstance(op, Mirror) and part.name == "motion/euler" and rig.pairs is not None:
            orders = np.asarray(rig.euler_orders)
            if not np.array_equal(orders, orders[rig.pairs]):
                raise InputError("mirror of motion/euler needs left and right twins of one order")


def _signs(axis: int) -> np.ndarray:
    s = np.ones(3)
    s[axis] = -1.0
    return s


def _mirror_part(x: np.ndarray, part: ColumnPart, rig: Rig, lateral: int) -> np.ndarray:
    """(L, *shape) values of one part, mirrored."""
    category = _category(part)
    s = _signs(lateral)
    if category == "invariant":
        return x
    if category == "trans":
        return x * s
    x = x[:, rig.pairs]
    if category == "joint_scalar":
        return x
    if category in ("world", "local"):
        return x * s
    array = part.name.split("/", 1)[1]
    keep = -s  # +1 on the lateral axis, −1 on the other two: rotation vectors, M R M
    if category == "angular" or array == "axis_angle":
        return x * keep
    if array == "quat":
        return x * np.concatenate([[1.0], keep])
    if array == "rotmat":
        return x * np.outer(s, s)
    if array == "rot6d":  # columns 0 and 1 of R: entries (0,0) (1,0) (2,0) (0,1) (1,1) (2,1)
        return x * np.concatenate([s * s[0], s * s[1]])
    if array == "rot6d_rows":  # rows 0 and 1 of R
        return x * np.concatenate([s[0] * s, s[1] * s])
    # euler: the angle about each axis of the joint's order kept if lateral, else negated
    letters = "xyz"
    signs = np.array(
        [[keep[letters.index(c.lower())] for c in order] for order in rig.euler_orders]
    )
    return x * signs


def mirror_rows(rows: np.ndarray, plan: list[ColumnPart], rig: Rig, lateral_axis: int = 0):
    """(L, D) rows mirrored part by part (:func:`check_augmentable` first)."""
    out = np.array(rows, dtype=np.float32, copy=True)
    for part in plan:
        x = out[:, part.start : part.stop].reshape((len(out), *part.shape))
        mirrored = _mirror_part(x.astype(np.float64), part, rig, lateral_axis)
        out[:, part.start : part.stop] = mirrored.reshape(len(out), -1)
    return out


def _turn(rotmat: np.ndarray, yaw: np.ndarray) -> np.ndarray:
    return np.einsum("ij,...jk->...ik", yaw, rotmat)


def _quat_product(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Hamilton product a ⊗ b of wxyz quaternions (a (4,), b (..., 4))."""
    w1, v1 = a[0], a[1:]
    w2, v2 = b[..., :1], b[..., 1:]
    return np.concatenate([w1 * w2 - v2 @ v1[:, None], w1 * v2 + w2 * v1 + np.cross(v1, v2)], -1)


def _yaw_root(x: np.ndarray, array: str, yaw: np.ndarray, order: str, qy: np.ndarray):
    """(L, width) root rotations of one representation turned by the yaw (matrix ``yaw``,
    wxyz quaternion ``qy``; the quaternion product keeps the stored sign continuity)."""
    if array == "rotmat":
        return _turn(x, yaw)
    if array == "quat":
        return _quat_product(qy, x)
    if array == "rot6d":  # the two stored columns of R rotate as vectors
        return np.concatenate([x[:, :3] @ yaw.T, x[:, 3:] @ yaw.T], axis=1)
    if array == "rot6d_rows":
        return rotmat_to_rot6d_rows(_turn(rot6d_rows_to_rotmat(x), yaw))
    if array == "axis_angle":
        return rotmat_to_axis_angle(_turn(axis_angle_to_rotmat(x), yaw))
    return rotmat_to_euler(_turn(euler_to_rotmat(x, order), yaw), order)


def yaw_rows(rows: np.ndarray, plan: list[ColumnPart], rig: Rig, angle_rad: float):
    """(L, D) rows turned by ``angle_rad`` about ``rig.up_axis`` through the world origin."""
    vector = np.zeros(3)
    vector[rig.up_axis] = angle_rad
    yaw = Rotation.from_rotvec(vector).as_matrix()
    qy = np.concatenate([[np.cos(angle_rad / 2)], np.sin(angle_rad / 2) * (vector != 0)])
    out = np.array(rows, dtype=np.float32, copy=True)
    for part in plan:
        category = _category(part)
        if category in ("invariant", "local", "joint_scalar"):
            continue
        x = out[:, part.start : part.stop].reshape((len(out), *part.shape)).astype(np.float64)
        array = part.name.split("/", 1)[1]
        if category in ("trans", "world"):
            x = x @ yaw.T
        elif category == "angular":
            x[:, rig.root] = x[:, rig.root] @ yaw.T
        else:
            order = rig.euler_orders[rig.root] if array == "euler" else ""
            x[:, rig.root] = _yaw_root(x[:, rig.root], array, yaw, order, qy)
        out[:, part.start : part.stop] = x.reshape(len(out), -1)
    return out
