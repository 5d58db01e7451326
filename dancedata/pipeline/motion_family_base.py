"""The shared base of the motion feature families: the batch they read, their settings and the
interface each implements.

Kept apart from the registry (:mod:`dancedata.pipeline.motion_families`) so that the family
modules import this one and the registry imports the families: imports run one way, with no
cycle. featurize reads the motion in batches of consecutive *whole* sequences (see
:class:`MotionBatch`); a family declares the arrays it writes (:class:`ArraySpec`) and returns
them with one row per frame of the batch.
"""

from __future__ import annotations

import os
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from dancedata.compute.motion_representations import REPRESENTATIONS, EulerOrder
from dancedata.pipeline.audio_families import ArraySpec

__all__ = ["BASE_ARRAYS", "ArraySpec", "MotionBatch", "MotionFamily", "MotionSettings"]

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
    # SMPL model file for the positions family (see dancedata.io.smpl_model); the CLI's
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
