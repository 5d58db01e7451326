"""Forward kinematics, vectorised over frames.

Convention (BVH, SMPL): a joint's local rotation ``R_j`` and translation ``t_j`` place it in its
parent's frame, so ``G_j = G_parent @ [R_j | t_j]``: world rotation ``W_j = W_p @ R_j`` and world
position ``x_j = x_p + W_p @ t_j``. The root's position is its translation. Lengths are in the
units of the offsets (file units, metres for a store).
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

__all__ = ["forward_kinematics", "topological_order", "transform_points", "world_transforms"]


def topological_order(parents: Sequence[int]) -> list[int]:
    """Joint indices with every parent before its children (raises ValueError on a cycle or a
    parent index out of range)."""
    parents = [int(p) for p in parents]
    n = len(parents)
    children: list[list[int]] = [[] for _ in range(n)]
    order = []
    for j, p in enumerate(parents):
        if p < 0:
            order.append(j)
        elif p >= n:
            raise ValueError(f"joint {j} has parent {p}, out of range")
        else:
            children[p].append(j)
    i = 0
    while i < len(order):
        order.extend(children[order[i]])
        i += 1
    if len(order) != n:
        raise ValueError("parents do not form a forest (cycle?)")
    return order


def world_transforms(
    parents: Sequence[int],
    offsets: np.ndarray,
    local_rotations: np.ndarray,
    root_translation: np.ndarray | None = None,
    joint_translations: np.ndarray | None = None,
) -> tuple[np.ndarray, np.ndarray]:
    """World rotations (F, J, 3, 3) and positions (F, J, 3).

    Args:
        parents: (J,) parent index per joint, -1 for a root.
        offsets: (J, 3) rest translation of each joint from its parent.
        local_rotations: (F, J, 3, 3) local rotation matrices.
        root_translation: optional (F, 3); replaces the translation of every root joint.
        joint_translations: optional (F, J, 3) per-frame local translations replacing
            ``offsets`` (BVH joints with position channels; the root included).
    """
    local_rotations = np.asarray(local_rotations, dtype=np.float64)
    n_frames, n_joints = local_rotations.shape[:2]
    if local_rotations.shape != (n_frames, n_joints, 3, 3) or len(parents) != n_joints:
        raise ValueError(
            f"need local_rotations (F, {len(parents)}, 3, 3), got {local_rotations.shape}"
        )
    offsets = np.asarray(offsets, dtype=np.float64).reshape(n_joints, 3)
    if joint_translations is None:
        trans = np.broadcast_to(offsets, (n_frames, n_joints, 3))
    else:
        trans = np.asarray(joint_translations, dtype=np.float64)
        if trans.shape != (n_frames, n_joints, 3):
            raise ValueError(f"joint_translations must be (F, J, 3), got {trans.shape}")
    if root_translation is not None:
        root_translation = np.asarray(root_translation, dtype=np.float64).reshape(n_frames, 3)

    rot = np.empty_like(local_rotations)
    pos = np.empty((n_frames, n_joints, 3))
    for j in topological_order(parents):
        p = int(parents[j])
        if p < 0:
            rot[:, j] = local_rotations[:, j]
            pos[:, j] = trans[:, j] if root_translation is None else root_translation
        else:
            rot[:, j] = rot[:, p] @ local_rotations[:, j]
            pos[:, j] = pos[:, p] + (rot[:, p] @ trans[:, j, :, None])[..., 0]
    return rot, pos


def forward_kinematics(
    parents: Sequence[int],
    offsets: np.ndarray,
    local_rotations: np.ndarray,
    root_translation: np.ndarray | None = None,
    joint_translations: np.ndarray | None = None,
) -> np.ndarray:
    """World joint positions (F, J, 3); see :func:`world_transforms` for the arguments."""
    return world_transforms(
        parents, offsets, local_rotations, root_translation, joint_translations
    )[1]


def transform_points(
    world_rotations: np.ndarray,
    world_positions: np.ndarray,
    joints: Sequence[int],
    local_points: np.ndarray,
) -> np.ndarray:
    """World positions (F, K, 3) of points fixed in joint frames, e.g. BVH End Sites:
    ``x = x_j + W_j @ p`` for point k attached to ``joints[k]`` at ``local_points[k]``."""
    idx = np.asarray(joints, dtype=np.int64)
    local_points = np.asarray(local_points, dtype=np.float64).reshape(len(idx), 3)
    return world_positions[:, idx] + (world_rotations[:, idx] @ local_points[..., None])[..., 0]
