"""Joint rotations from joint positions: bone-direction inverse kinematics on a rest skeleton.

Pose lifters (HMR, VideoPose3D, ...) write world joint positions; BVH and every rotation
representation need local joint rotations. This module solves them, vectorised over frames.

Rest skeleton (:func:`rest_skeleton`), measured from the data:

* bone length of joint j = the median over frames of ``|x_j - x_parent(j)|`` (frames where
  both ends are known);
* rest direction of that bone = its direction in the *first frame where both ends are known*
  ("first-frame rest": the rest pose is the first observed pose, so a sequence whose first frame
  is complete has identity local rotations there). The root's offset is zero.

Rotations (:func:`solve_rotations`), joints visited parents first; ``W`` is a joint's world
rotation, ``R = W_parent^T W`` its local rotation, ``r_c`` the rest offset direction of child c
(in the joint's frame, which is the world frame at rest), ``d_c`` the observed direction
``x_c - x_j``:

* **two or more children** whose directions are known: ``W`` is the best-fit rotation taking
  every ``r_c`` to ``d_c`` (Wahba's problem with unit weights on unit directions, solved by SVD,
  the Kabsch method with the reflection removed). The children fix the twist.
* **one child** (or only one known): ``R`` is the shortest-arc rotation (swing only) taking
  ``r_c`` to ``W_parent^T d_c``: zero twist about the bone relative to the parent's solved frame.
* **no child** (a leaf) or no known child direction in that frame: ``R`` = identity.

The root translation is the observed root position. Forward kinematics of the result
(:func:`dancedata.compute.fk.forward_kinematics` with the rest offsets) puts every child
direction exactly on the observed one for single-child joints, and in the least-squares sense
for several children; positions are exact when the observations are a rigid pose of the rest
skeleton (bone lengths constant, angles between sibling bones constant). Otherwise the residual
is what a rigid skeleton cannot follow (:func:`fk_residual` measures it per frame and joint).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from dancedata.compute.fk import forward_kinematics, topological_order

__all__ = [
    "IK_METHOD",
    "IkSolution",
    "best_fit_rotation",
    "fk_residual",
    "rest_skeleton",
    "shortest_arc",
    "solve_rotations",
]

IK_METHOD = {
    "name": "bone_direction_ik",
    "rest_lengths": "median over frames of the observed parent-child distances",
    "rest_directions": "first frame in which both ends of the bone are known",
    "several_children": "best-fit world rotation of all child directions (Wahba/Kabsch, unit "
    "weights, reflection removed): twist fixed by the children",
    "one_child": "shortest-arc local rotation (swing only, zero twist about the bone relative to "
    "the parent's solved frame)",
    "leaf_or_unknown": "identity local rotation",
    "root_translation": "observed root position (rest root offset 0)",
}

_EPS = 1e-12


def _children(parents: Sequence[int]) -> list[list[int]]:
    kids: list[list[int]] = [[] for _ in parents]
    for j, p in enumerate(parents):
        if p >= 0:
            kids[int(p)].append(j)
    return kids


def _unit(v: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Unit vectors along the last axis and whether each was finite and non-zero."""
    norm = np.linalg.norm(v, axis=-1, keepdims=True)
    ok = np.isfinite(norm[..., 0]) & (norm[..., 0] > _EPS)
    safe = np.where(ok[..., None], norm, 1.0)
    return np.where(ok[..., None], v / safe, 0.0), ok


def rest_skeleton(positions: np.ndarray, parents: Sequence[int]) -> np.ndarray:
    """Rest offsets (J, 3) of each joint from its parent, in the positions' units.

    Lengths: median over frames of the observed bone lengths; directions: the bone's direction in
    the first frame where both its ends are known (module docstring). The root's offset is zero.

    Raises:
        ValueError: when a bone is never observed (no frame knows both its ends) or has zero
            length in its first observed frame.
    """
    positions = np.asarray(positions, dtype=np.float64)
    n_joints = len(parents)
    if positions.ndim != 3 or positions.shape[1:] != (n_joints, 3):
        raise ValueError(f"positions must be (F, {n_joints}, 3), got {positions.shape}")
    offsets = np.zeros((n_joints, 3))
    for j, p in enumerate(parents):
        if p < 0:
            continue
        bone = positions[:, j] - positions[:, int(p)]
        direction, ok = _unit(bone)
        if not ok.any():
            raise ValueError(f"bone {p}->{j} is never observed (no frame knows both ends)")
        length = float(np.median(np.linalg.norm(bone[ok], axis=-1)))
        offsets[j] = length * direction[int(np.argmax(ok))]
    return offsets


def shortest_arc(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """(..., 3, 3) rotations taking unit vectors ``a`` to unit vectors ``b`` about ``a × b``
    (no twist). Opposite vectors get a half turn about an axis perpendicular to ``a``."""
    a = np.asarray(a, dtype=np.float64)
    b = np.asarray(b, dtype=np.float64)
    a, b = np.broadcast_arrays(a, b)
    v = np.cross(a, b)
    c = np.einsum("...i,...i->...", a, b)
    k = np.zeros(a.shape[:-1] + (3, 3))
    k[..., 0, 1], k[..., 0, 2] = -v[..., 2], v[..., 1]
    k[..., 1, 0], k[..., 1, 2] = v[..., 2], -v[..., 0]
    k[..., 2, 0], k[..., 2, 1] = -v[..., 1], v[..., 0]
    opposite = (1.0 + c) < 1e-9
    scale = np.where(opposite, 0.0, 1.0 / np.where(opposite, 1.0, 1.0 + c))
    rot = np.eye(3) + k + (k @ k) * scale[..., None, None]
    if opposite.any():
        av = a[opposite]
        helper = np.eye(3)[np.argmin(np.abs(av), axis=-1)]
        u, _ = _unit(np.cross(av, helper))
        rot[opposite] = 2.0 * u[:, :, None] * u[:, None, :] - np.eye(3)
    return rot


def best_fit_rotation(rest: np.ndarray, observed: np.ndarray, weights: np.ndarray) -> np.ndarray:
    """(F, 3, 3) rotations ``W`` minimising ``sum_c w_c |W rest_c - observed_c|^2``.

    Args:
        rest: (C, 3) or (F, C, 3) vectors in the rest frame.
        observed: (F, C, 3) vectors to match.
        weights: (F, C) non-negative weights (0 leaves a vector out).

    Kabsch: ``H = sum_c w_c rest_c observed_c^T = U S V^T``, ``W = V diag(1, 1, det(V U^T)) U^T``.
    """
    rest = np.broadcast_to(np.asarray(rest, dtype=np.float64), np.shape(observed))
    h = np.einsum("fc,fci,fcj->fij", weights, rest, np.nan_to_num(observed))
    u, _, vt = np.linalg.svd(h)
    v = np.swapaxes(vt, -1, -2)
    d = np.sign(np.linalg.det(v @ np.swapaxes(u, -1, -2)))
    d = np.where(d == 0, 1.0, d)
    v[..., :, 2] *= d[..., None]
    return v @ np.swapaxes(u, -1, -2)


@dataclass(frozen=True)
class IkSolution:
    """Solved motion.

    Attributes:
        local_rotations: (F, J, 3, 3) local rotation of each joint (identity where undetermined).
        root_translation: (F, 3) observed root position (NaN where the root is missing).
        solved: (F, J) uint8 how each rotation was found: 0 identity (leaf or no known child),
            1 shortest arc from one child, 2 best fit of several children.
    """

    local_rotations: np.ndarray
    root_translation: np.ndarray
    solved: np.ndarray


def solve_rotations(
    positions: np.ndarray, parents: Sequence[int], offsets: np.ndarray
) -> IkSolution:
    """Local joint rotations (F, J, 3, 3) posing the rest skeleton ``offsets`` (J, 3) onto the
    observed world ``positions`` (F, J, 3); the rules are in the module docstring. NaN
    positions are missing joints.

    Raises:
        ValueError: on shapes that disagree, a parent index out of range or a cycle, or a
            skeleton with more than one root.
    """
    positions = np.asarray(positions, dtype=np.float64)
    offsets = np.asarray(offsets, dtype=np.float64)
    parents = [int(p) for p in parents]
    n_frames, n_joints = positions.shape[0], len(parents)
    if positions.shape != (n_frames, n_joints, 3) or offsets.shape != (n_joints, 3):
        raise ValueError(
            f"need positions (F, {n_joints}, 3) and offsets ({n_joints}, 3), got "
            f"{positions.shape} and {offsets.shape}"
        )
    order = topological_order(parents)
    roots = [j for j in range(n_joints) if parents[j] < 0]
    if len(roots) != 1:
        raise ValueError(f"the skeleton needs one root, it has {len(roots)}")
    kids = _children(parents)
    rest_dir, _ = _unit(offsets)
    world = np.empty((n_frames, n_joints, 3, 3))
    local = np.broadcast_to(np.eye(3), (n_frames, n_joints, 3, 3)).copy()
    solved = np.zeros((n_frames, n_joints), np.uint8)
    for j in order:
        p = parents[j]
        parent_world = np.broadcast_to(np.eye(3), (n_frames, 3, 3)) if p < 0 else world[:, p]
        cs = [c for c in kids[j] if np.linalg.norm(offsets[c]) > _EPS]
        if cs:
            observed, known = _unit(positions[:, cs] - positions[:, j : j + 1])
            count = known.sum(axis=1)
            one = count == 1
            if one.any():  # swing of the one known child, in the parent's frame
                first = np.argmax(known[one], axis=1)
                target = observed[one, first]
                target_local = np.einsum("fji,fj->fi", parent_world[one], target)
                local[one, j] = shortest_arc(rest_dir[np.asarray(cs)[first]], target_local)
                solved[one, j] = 1
            many = count >= 2
            if many.any():
                fit = best_fit_rotation(
                    rest_dir[cs], observed[many], known[many].astype(np.float64)
                )
                local[many, j] = np.swapaxes(parent_world[many], -1, -2) @ fit
                solved[many, j] = 2
        world[:, j] = parent_world @ local[:, j]
    return IkSolution(local, positions[:, roots[0]].copy(), solved)


def fk_residual(
    positions: np.ndarray,
    parents: Sequence[int],
    offsets: np.ndarray,
    local_rotations: np.ndarray,
    root_translation: np.ndarray,
) -> np.ndarray:
    """(F, J) distance between forward kinematics of the solution and the observed positions
    (NaN where the observation is missing), in the positions' units."""
    fk = forward_kinematics(parents, offsets, local_rotations, root_translation)
    return np.linalg.norm(fk - np.asarray(positions, dtype=np.float64), axis=-1)
