"""Motion feature families: each computes a set of ``motion/...`` arrays from a batch of whole
sequences.

featurize reads the motion in batches of consecutive *whole* sequences (about one zarr chunk of
frames each), so a family can use neighbouring frames (velocities, sign continuity) without
state carried between batches, and batches are independent work units. A family declares the
arrays it writes and returns them with one row per frame of the batch.

To add a family, subclass :class:`MotionFamily` and add an instance to :data:`FAMILIES`.
"""

from __future__ import annotations

from dataclasses import dataclass
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


@dataclass(frozen=True)
class MotionBatch:
    """Consecutive whole sequences: arrays over the batch's frames plus sequence bounds.

    ``bounds`` is (S, 2) half-open [start, stop) of each sequence relative to the batch.
    ``attrs`` are the ``motion`` group attrs (fps, skeleton, ...); ``fps`` in frames/second.
    """

    axis_angle: np.ndarray  # (n, J, 3) float64, radians
    trans: np.ndarray  # (n, 3) float64, metres
    bounds: np.ndarray
    attrs: dict[str, Any]

    @property
    def n_joints(self) -> int:
        return int(self.axis_angle.shape[1])

    def sequences(self) -> list[slice]:
        return [slice(int(a), int(b)) for a, b in self.bounds]


@dataclass
class MotionSettings:
    """Settings every motion family may read; all are fingerprinted via ``config()``."""

    representations: tuple[str, ...] = REPRESENTATIONS
    euler_order: EulerOrder = "XYZ"


class MotionFamily:
    name: str = ""

    def arrays(self, n_joints: int, settings: MotionSettings) -> list[ArraySpec]:
        raise NotImplementedError

    def compute(self, batch: MotionBatch, settings: MotionSettings) -> dict[str, np.ndarray]:
        raise NotImplementedError

    def config(self, settings: MotionSettings) -> dict[str, Any]:
        return {}


class RotationsFamily(MotionFamily):
    """rotmat, euler, quat (wxyz, sign-continuous within each sequence) and rot6d."""

    name = "rotations"

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


FAMILIES: dict[str, MotionFamily] = {"rotations": RotationsFamily()}
DEFAULT_FAMILIES: tuple[str, ...] = ("rotations",)
