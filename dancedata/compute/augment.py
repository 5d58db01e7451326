"""Training augmentations of motion: left/right mirroring and rotation about the vertical axis.

Pure functions on local joint rotations (axis-angle, (F, J, 3), radians), the root translation
((F, 3), any length unit) and world joint positions ((F, J, 3)); axis 0 is time.

* **Mirror** reflects the motion in the body's sagittal plane (the plane normal to the lateral
  axis, x for SMPL/AIST++) and swaps left and right joints. A reflection M = I − 2 e eᵀ maps a
  rotation R to M R M, whose axis-angle vector is −M v: the component along the lateral axis is
  kept and the other two change sign. This is exact for positions computed by forward kinematics
  when the rest skeleton is itself mirror-symmetric (SMPL's is, up to the model's asymmetry);
  applied twice it is the identity, bit for bit.
* **Yaw** turns the whole motion by an angle about the vertical axis through the world origin:
  the root rotation is pre-multiplied, the translation and positions rotated. Horizontal speeds,
  heights and distances from the origin are unchanged, so kinetic and geometric features are.
"""

from __future__ import annotations

import re
from collections.abc import Sequence

import numpy as np
from scipy.spatial.transform import Rotation

__all__ = [
    "mirror_axis_angle",
    "mirror_pairs",
    "mirror_points",
    "yaw_axis_angle",
    "yaw_points",
]

# Name rules that turn a left joint's name into its right twin (and back), tried in order:
# words (left_hip, LeftUpLeg), then prefixes and suffixes (LThigh, l_knee, knee_l, Arm.L). Each
# rule is (pattern, replacement) for one direction; both directions are listed.
_WORDS = (("left", "right"), ("Left", "Right"), ("LEFT", "RIGHT"))
_AFFIXES = (
    (r"^{0}(?=[A-Z_.])", "{0}"),  # LThigh, L_Hip
    (r"^{0}(?=[A-Z])", "{0}"),  # lThigh (lower-case side letter)
    (r"_{0}$", "_{0}"),  # knee_l
    (r"\.{0}$", ".{0}"),  # Arm.L
)


def _rules() -> list[tuple[str, str]]:
    rules = []
    for a, b in _WORDS:
        rules += [(a, b), (b, a)]
    for pattern, replacement in _AFFIXES:
        for a, b in (("L", "R"), ("R", "L"), ("l", "r"), ("r", "l")):
            rules.append((pattern.format(a), replacement.format(b)))
    return rules


_SWAPS: tuple[tuple[str, str], ...] = tuple(_rules())


def _twin(name: str, names: set[str]) -> str:
    for pattern, replacement in _SWAPS:
        other = re.sub(pattern, replacement, name, count=1)
        if other != name and other in names:
            return other
    return name


def mirror_pairs(joint_names: Sequence[str]) -> np.ndarray:
    """(J,) permutation: index of each joint's left/right twin (itself for a centre joint).

    Raises ValueError when the pairing is not an involution (two joints claiming one twin)."""
    names = list(joint_names)
    index = {n: i for i, n in enumerate(names)}
    if len(index) != len(names):
        raise ValueError("joint names repeat: cannot pair left and right joints by name")
    perm = np.array([index[_twin(n, set(index))] for n in names], dtype=np.int64)
    if not np.array_equal(perm[perm], np.arange(len(names))):
        raise ValueError("left/right joint names do not pair one to one")
    return perm


def _axis(index: int) -> None:
    if index not in (0, 1, 2):
        raise ValueError(f"axis must be 0, 1 or 2 (x, y, z), got {index}")


def mirror_axis_angle(
    axis_angle: np.ndarray, translation: np.ndarray, pairs: np.ndarray, *, lateral_axis: int = 0
) -> tuple[np.ndarray, np.ndarray]:
    """Mirrored (axis_angle (F, J, 3), translation (F, 3)): joints swapped by ``pairs``, each
    rotation vector's non-lateral components negated, the translation's lateral one negated."""
    _axis(lateral_axis)
    aa = np.asarray(axis_angle)[:, np.asarray(pairs)].copy()
    keep = np.arange(3) == lateral_axis
    aa[..., ~keep] *= -1
    trans = np.asarray(translation).copy()
    trans[..., lateral_axis] *= -1
    return aa, trans


def mirror_points(points: np.ndarray, pairs: np.ndarray, *, lateral_axis: int = 0) -> np.ndarray:
    """Mirrored world positions (F, J, 3): joints swapped, the lateral coordinate negated."""
    _axis(lateral_axis)
    out = np.asarray(points)[:, np.asarray(pairs)].copy()
    out[..., lateral_axis] *= -1
    return out


def _yaw(angle_rad: float, up_axis: int) -> Rotation:
    _axis(up_axis)
    if not np.isfinite(angle_rad):
        raise ValueError(f"yaw angle must be finite, got {angle_rad}")
    vector = np.zeros(3)
    vector[up_axis] = angle_rad
    return Rotation.from_rotvec(vector)


def yaw_axis_angle(
    axis_angle: np.ndarray, translation: np.ndarray, angle_rad: float, *, up_axis: int = 1
) -> tuple[np.ndarray, np.ndarray]:
    """(axis_angle, translation) turned by ``angle_rad`` about the ``up_axis`` through the world
    origin: root rotation R₀ → Y R₀, translation t → Y t; other local rotations unchanged."""
    yaw = _yaw(angle_rad, up_axis)
    aa = np.array(axis_angle, dtype=np.float64)
    aa[:, 0] = (yaw * Rotation.from_rotvec(aa[:, 0])).as_rotvec()
    trans = yaw.apply(np.asarray(translation, dtype=np.float64))
    return aa, trans


def yaw_points(points: np.ndarray, angle_rad: float, *, up_axis: int = 1) -> np.ndarray:
    """World positions (F, J, 3) turned by ``angle_rad`` about ``up_axis`` through the origin."""
    p = np.asarray(points, dtype=np.float64)
    return _yaw(angle_rad, up_axis).apply(p.reshape(-1, 3)).reshape(p.shape)
