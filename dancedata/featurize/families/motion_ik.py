"""The ``rotations_from_positions`` motion family: joint rotations solved from joint positions.

For stores that hold only world joint positions (``ingest video --joints-csv``: a pose lifter's
3-d joints), so that they can be exported to BVH and featurized like any rotation store. Per
sequence (each video is its own person), a rest skeleton is measured from the data and the
rotations are solved by bone-direction inverse kinematics (:mod:`dancedata.compute.ik`; the
method, including the twist convention, is recorded in every array's ``method`` attr and so in
the featurize config of the manifest). Arrays written, one row per frame:

* ``motion/axis_angle`` (F, J, 3) float32 radians: local joint rotations (identity for leaves
  and where no child direction is known).
* ``motion/trans`` (F, 3) float32 metres: the observed root position; frames where the root is
  missing are linearly interpolated within the sequence (held at the ends).
* ``motion/ik_rest_offsets`` (F, J, 3) float32 metres: the sequence's rest skeleton (the same
  row on every frame of a sequence): each joint's offset from its parent, root zero.
* ``motion/ik_residual`` (F, J) float32 metres: distance of forward kinematics of the solution
  from the observed position (NaN where the observation is missing). Zero up to rounding for
  a rigid skeleton; larger where the lifter's bone lengths or sibling angles vary.
* ``motion/ik_solved`` (F, J) uint8: 0 identity, 1 shortest arc from one child, 2 best fit of
  several children.

Only for position-only stores: a skeleton with a bone structure (BODY_25 or COCO-18 joint names)
and no source rotations (BVH or SMPL stores are refused, their rotations are the data).
``featurize --motion-families rotations_from_positions,rotations`` also writes the other
representations (rotmat, euler, quat, rot6d) of the solved rotations, in the same run.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from dancedata.compute.ik import IK_METHOD, fk_residual, rest_skeleton, solve_rotations
from dancedata.compute.rotations import rotmat_to_axis_angle
from dancedata.errors import InputError
from dancedata.featurize.families.motion_base import (
    ArraySpec,
    MotionBatch,
    MotionFamily,
    MotionSettings,
)
from dancedata.featurize.family import register_family
from dancedata.featurize.source_arrays import source_array

__all__ = ["RotationsFromPositionsFamily", "solve_sequence"]

SOLVED_CODES = {"0": "identity (leaf or no known child)", "1": "shortest arc", "2": "best fit"}


def _check_skeleton(skeleton: dict[str, Any]) -> list[int]:
    parents = [int(p) for p in skeleton.get("parents") or []]
    name = skeleton.get("name")
    if skeleton.get("offsets") is not None or name == "smpl24":
        raise InputError(
            f"skeleton {name!r} has source rotations (motion/axis_angle); rotations_from_positions "
            "is for stores that hold joint positions only"
        )
    if sum(p < 0 for p in parents) != 1:
        raise InputError(
            f"skeleton {name!r} has no bone structure ({sum(p < 0 for p in parents)} roots): name "
            "the joints CSV's joints by a known set (BODY_25, COCO-18, H36M-17, SPIN-24, HMR-19) "
            "so that their parents are known"
        )
    return parents


def _interpolate_missing(values: np.ndarray) -> np.ndarray:
    """(F, 3) with NaN rows filled linearly from the known rows (held at the ends)."""
    known = np.isfinite(values).all(axis=1)
    if known.all():
        return values
    frames = np.arange(values.shape[0])
    return np.stack([np.interp(frames, frames[known], values[known, k]) for k in range(3)], axis=1)


def solve_sequence(
    positions: np.ndarray, parents: list[int], joints: list[str]
) -> dict[str, np.ndarray]:
    """The family's arrays (module docstring) for one sequence's (F, J, 3) positions."""
    n_frames = positions.shape[0]
    root = parents.index(-1)
    if not np.isfinite(positions[:, root]).all(axis=1).any():
        raise InputError(f"the root joint {joints[root]!r} is never observed in a sequence")
    try:
        offsets = rest_skeleton(positions, parents)
    except ValueError as exc:  # name the bone by its joints
        bone = str(exc).split()[1].split("->")
        raise InputError(
            f"bone {joints[int(bone[0])]}->{joints[int(bone[1])]} is never observed in a "
            "sequence, so it has no rest length"
        ) from None
    solution = solve_rotations(positions, parents, offsets)
    residual = fk_residual(
        positions, parents, offsets, solution.local_rotations, solution.root_translation
    )
    return {
        "axis_angle": rotmat_to_axis_angle(solution.local_rotations),
        "trans": _interpolate_missing(solution.root_translation),
        "ik_rest_offsets": np.broadcast_to(offsets, (n_frames, *offsets.shape)),
        "ik_residual": residual,
        "ik_solved": solution.solved,
    }


def _ik_output(path: str, row_shape: tuple, dtype: type, *attrs: str) -> ArraySpec:
    return ArraySpec(path, row_shape, dtype, required_attrs=(*attrs, "method"), extension=True)


@register_family("rotations_from_positions")
class RotationsFromPositionsFamily(MotionFamily):
    """Joint rotations and root translation from ``motion/positions`` (module docstring)."""

    inputs = (source_array("positions"),)
    outputs = (
        source_array("axis_angle"),
        source_array("trans"),
        _ik_output("ik_rest_offsets", ("J", 3), np.float32, "units", "of"),
        _ik_output("ik_residual", ("J",), np.float32, "units", "missing"),
        _ik_output("ik_solved", ("J",), np.uint8, "codes"),
    )

    def arrays(self, n_joints: int, settings: MotionSettings) -> list[ArraySpec]:
        method = {"method": IK_METHOD, "from": "motion/positions"}
        return [
            ArraySpec("axis_angle", (n_joints, 3), np.float32, {"units": "rad", **method}),
            ArraySpec("trans", (3,), np.float32, {"units": "m", **method}),
            ArraySpec(
                "ik_rest_offsets",
                (n_joints, 3),
                np.float32,
                {"units": "m", "of": "the sequence's rest skeleton (root 0)", **method},
            ),
            ArraySpec(
                "ik_residual",
                (n_joints,),
                np.float32,
                {"units": "m", "missing": "NaN where the observed position is NaN", **method},
            ),
            ArraySpec("ik_solved", (n_joints,), np.uint8, {"codes": SOLVED_CODES, **method}),
        ]

    def compute(self, batch: MotionBatch, settings: MotionSettings) -> dict[str, np.ndarray]:
        skeleton = batch.attrs.get("skeleton") or {}
        parents = _check_skeleton(skeleton)
        joints = list(skeleton.get("joints") or [])
        positions = batch.arrays["positions"]
        n_frames, n_joints = positions.shape[:2]
        out = {
            spec.path: np.zeros((n_frames, *spec.row_shape), spec.dtype)
            for spec in self.arrays(n_joints, settings)
        }
        for part in batch.sequences():
            for name, values in solve_sequence(positions[part], parents, joints).items():
                out[name][part] = values
        return out

    def config(self, settings: MotionSettings) -> dict[str, Any]:
        return {"method": IK_METHOD}
