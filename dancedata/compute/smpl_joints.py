"""SMPL posed joints: forward kinematics of an axis-angle pose about a model's rest joints.

The model file is read by :mod:`dancedata.io.smpl_model`; this is the joint solver on its
arrays (issue 15 item 3: formats parse, operations compute). SMPL without pose blend shapes
(they do not move joints): the root rotates about its rest position, then translates.
"""

from __future__ import annotations

from typing import Protocol

import numpy as np

from dancedata.compute.fk import forward_kinematics
from dancedata.compute.rotations import axis_angle_to_rotmat

__all__ = ["SmplJointModel", "smpl_joint_positions"]


class SmplJointModel(Protocol):
    """What the solver needs of a model (:class:`dancedata.io.smpl_model.SmplModel` has it)."""

    @property
    def parents(self) -> tuple[int, ...]: ...

    @property
    def n_joints(self) -> int: ...

    def joint_offsets(self, betas: np.ndarray | None = None) -> np.ndarray: ...


def smpl_joint_positions(
    model: SmplJointModel,
    axis_angle: np.ndarray,
    trans: np.ndarray,
    betas: np.ndarray | None = None,
) -> np.ndarray:
    """(F, J, 3) world joint positions in metres from (F, J, 3) axis-angle (radians, root
    first) and (F, 3) translation (metres): SMPL's posed joints, ``J_posed + trans``."""
    axis_angle = np.asarray(axis_angle, dtype=np.float64)
    if axis_angle.ndim != 3 or axis_angle.shape[1:] != (model.n_joints, 3):
        raise ValueError(f"need axis_angle (F, {model.n_joints}, 3), got {axis_angle.shape}")
    trans = np.asarray(trans, dtype=np.float64).reshape(-1, 3)
    offsets = model.joint_offsets(betas)
    root = offsets[0] + trans  # the root rotates about its rest position, then translates
    return forward_kinematics(
        model.parents, offsets, axis_angle_to_rotmat(axis_angle), root_translation=root
    )
