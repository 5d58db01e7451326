"""Motion feature families: each computes a set of ``motion/...`` arrays from a batch of whole
sequences.

featurize reads the motion in batches of consecutive *whole* sequences (about one zarr chunk of
frames each), so a family can use neighbouring frames (velocities, sign continuity) without
state carried between batches, and batches are independent work units. A family declares the
arrays it writes and returns them with one row per frame of the batch.

To add a family, subclass :class:`MotionFamily` and add an instance to :data:`FAMILIES`.
"""

from __future__ import annotations

import os
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from dancedata.compute.motion_representations import (
    REPRESENTATIONS,
    EulerOrder,
    continue_quat_signs,
    representation_attrs,
    representations_from_axis_angle,
    row_shape,
)
from dancedata.pipeline.audio_families import ArraySpec

# Arrays a family may read, as ingest stores them (whichever of them the store has).
BASE_ARRAYS: tuple[str, ...] = (
    "axis_angle",  # (F, J, 3) radians
    "trans",  # (F, 3) metres
    "euler",  # (F, J, 3) radians, BVH: each joint's own order
    "positions",  # (F, J, 3) metres, world joint positions
    "keypoints3d",  # (F, 17, 3) metres
    "keypoints2d",  # AIST++ (F, 9 views, 17, 3): x, y pixels, confidence
    "pose2d",  # video (F, J, 3): one tracked dancer, x, y pixels, confidence
)


@dataclass(frozen=True)
class MotionBatch:
    """Consecutive whole sequences: base arrays over the batch's frames, sequence bounds.

    ``arrays`` maps base array names (see :data:`BASE_ARRAYS`) present in the store to float64
    arrays of the batch's frames. ``bounds`` is (S, 2) half-open [start, stop) of each
    sequence relative to the batch. ``attrs`` are the ``motion`` group attrs (``fps`` in
    frames/second, ``skeleton``, ...).
    """

    arrays: dict[str, np.ndarray]
    bounds: np.ndarray
    attrs: dict[str, Any]

    @property
    def axis_angle(self) -> np.ndarray:
        return self.arrays["axis_angle"]

    def sequences(self) -> list[slice]:
        return [slice(int(a), int(b)) for a, b in self.bounds]


@dataclass
class MotionSettings:
    """Settings every motion family may read; all are fingerprinted via ``config()``."""

    representations: tuple[str, ...] = REPRESENTATIONS
    euler_order: EulerOrder = "XYZ"
    # SMPL model file for the positions family (see dancedata.smpl_model); the CLI's
    # --smpl-model sets $DANCEDATA_SMPL_MODEL.
    smpl_model: str | None = field(default_factory=lambda: os.environ.get("DANCEDATA_SMPL_MODEL"))


class MotionFamily:
    """Base class. ``requires`` names the base arrays the family reads; when the store lacks
    one, featurize skips the family and reports its arrays as absent (never zero-filled)."""

    name: str = ""
    requires: tuple[str, ...] = ()

    def arrays(self, n_joints: int, settings: MotionSettings) -> list[ArraySpec]:
        raise NotImplementedError

    def compute(self, batch: MotionBatch, settings: MotionSettings) -> dict[str, np.ndarray]:
        raise NotImplementedError

    def config(self, settings: MotionSettings) -> dict[str, Any]:
        return {}


class RotationsFamily(MotionFamily):
    """rotmat, euler, quat (wxyz, sign-continuous within each sequence), rot6d (Zhou's
    columns) and, on request, rot6d_rows (pytorch3d's and EDGE's rows)."""

    name = "rotations"
    requires = ("axis_angle",)

    def arrays(self, n_joints: int, settings: MotionSettings) -> list[ArraySpec]:
        return [
            ArraySpec(
                name,
                row_shape(name, n_joints),
                np.float32,
                representation_attrs(name, settings.euler_order),
            )
            for name in settings.representations
        ]

    def compute(self, batch: MotionBatch, settings: MotionSettings) -> dict[str, np.ndarray]:
        reps = representations_from_axis_angle(
            batch.axis_angle, settings.representations, settings.euler_order
        )
        if "quat" in reps:
            quat = reps["quat"]
            for part in batch.sequences():
                quat[part] = continue_quat_signs(quat[part], None)
        return reps

    def config(self, settings: MotionSettings) -> dict[str, Any]:
        return {
            "representations": sorted(settings.representations),
            "euler_order": settings.euler_order,
        }


def _more_families() -> dict[str, MotionFamily]:
    """Families defined in their own modules (duck-typed MotionFamily, so no import cycle)."""
    from dancedata.pipeline.motion_families_ik import RotationsFromPositionsFamily
    from dancedata.pipeline.motion_families_kinematics import (
        AngularFamily,
        GeometricFamily,
        KinematicsFamily,
    )
    from dancedata.pipeline.motion_families_positions import PositionsFamily

    families = (
        PositionsFamily(),
        KinematicsFamily(),
        AngularFamily(),
        GeometricFamily(),
        RotationsFromPositionsFamily(),
    )
    return {family.name: family for family in families}  # type: ignore[misc]


FAMILIES: dict[str, MotionFamily] = {"rotations": RotationsFamily(), **_more_families()}
DEFAULT_FAMILIES: tuple[str, ...] = ("rotations",)
