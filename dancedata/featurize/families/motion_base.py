"""The base of the motion feature families: the batch they read and how they compute.

featurize reads the motion in batches of consecutive *whole* sequences (see
:class:`MotionBatch`); a family (:class:`MotionFamily`, a
:class:`~dancedata.featurize.family.Family` with group ``motion``) declares the arrays it reads
and writes (:class:`ArraySpec`) and returns its arrays with one row per frame of the batch. An
input can come from the store or from a family that ran before it in the same run: featurize
puts that family's output into the batch, rounded to its stored dtype, so the numbers are those
a second run would read back.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any, ClassVar

import numpy as np

from dancedata.featurize.family import ArraySpec, Family
from dancedata.featurize.family_settings import MotionSettings
from dancedata.featurize.source_arrays import BASE_ARRAYS

__all__ = ["BASE_ARRAYS", "ArraySpec", "MotionBatch", "MotionFamily", "MotionSettings"]


@dataclass(frozen=True)
class MotionBatch:
    """Consecutive whole sequences: input arrays over the batch's frames, sequence bounds.

    ``arrays`` maps array names (see :data:`BASE_ARRAYS`, or outputs of families that ran
    earlier in the run) to float64 arrays of the batch's frames. ``bounds`` is (S, 2) half-open
    [start, stop) of each sequence relative to the batch. ``attrs`` are the ``motion`` group
    attrs (``fps`` in frames/second, ``skeleton``, ...).
    """

    arrays: dict[str, np.ndarray]
    bounds: np.ndarray
    attrs: dict[str, Any]

    @property
    def axis_angle(self) -> np.ndarray:
        return self.arrays["axis_angle"]

    def sequences(self) -> list[slice]:
        return [slice(int(a), int(b)) for a, b in self.bounds]


class MotionFamily(Family):
    """Base class. ``inputs`` names the arrays the family reads; when neither the store nor an
    earlier family of the run has one, featurize skips the family and reports its arrays as
    absent (never zero-filled)."""

    group: ClassVar[str] = "motion"
    settings_type: ClassVar[type] = MotionSettings

    def arrays(self, n_joints: int, settings: MotionSettings) -> list[ArraySpec]:
        raise NotImplementedError

    def compute(self, batch: MotionBatch, settings: MotionSettings) -> dict[str, np.ndarray]:
        raise NotImplementedError
