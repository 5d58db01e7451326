"""Motion feature families computed on request: kinematics of joint positions, angular velocity
of joint rotations, and the geometric (Müller) features of SMPL-24 poses.

Each class subclasses :class:`~dancedata.featurize.families.motion_base.MotionFamily` (``inputs``,
``outputs``, ``arrays``, ``compute``, ``config``) and registers itself
(:func:`~dancedata.featurize.family.register_family`).

Every array has one row per frame, like every motion array (featurize writes frame rows):

* Finite differences of a sequence of n frames have n − k values (k = 1, 2, 3). Row t holds
  the forward difference starting at frame t (velocity: ``(p[t+1] − p[t])·fps``); the last k
  rows of each sequence repeat the last defined row (all zeros when n ≤ k).
* Per-sequence features (kinetic, geometric) are written on every frame of their sequence:
  read row ``frame_start`` of a sequence. Constant rows cost almost nothing once compressed.

Families and the arrays they read, from the store or from a family earlier in the same run
(``positions`` then ``kinematics`` in one run; a run lacking one reports the family absent):

* ``kinematics`` (positions): velocity, acceleration, jerk (m/s, m/s², m/s³ at the store fps),
  motion beats (mint and Bailando variants), kinetic features (3 per joint; 72-d for SMPL-24)
  in parity and corrected modes. Works on any skeleton, e.g. video-derived positions.
* ``angular`` (axis_angle): per-joint angular velocity of the local rotations (rad/s, in the
  parent's frame) and the Laban weight effort (summed joint angular speed).
* ``geometric`` (positions, SMPL-24 only): the 32 boolean predicates of Müller et al. averaged
  over each sequence, with the reference's 1/120 s velocity time step.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from dancedata.compute.motion_features import (
    angular_velocity,
    geometric_features,
    kinetic_features,
    motion_beats_bailando,
    motion_beats_mint,
)
from dancedata.compute.rotations import axis_angle_to_quat
from dancedata.errors import InputError
from dancedata.featurize.families.motion_base import (
    ArraySpec,
    MotionBatch,
    MotionFamily,
    MotionSettings,
)
from dancedata.featurize.family import register_family
from dancedata.featurize.source_arrays import source_array

__all__ = ["AngularFamily", "GeometricFamily", "KinematicsFamily", "forward_rows"]

MINT_ORDER = 10  # frames either side (mint / FACT, at 60 fps)
BAILANDO_SIGMA = 5.0  # Gaussian smoothing of the speed, frames
GEOMETRIC_FRAME_TIME_S = 1.0 / 120.0  # the reference's velocity time step (parity)
_FORWARD = "row t = forward difference from frame t; the last {k} row(s) of each sequence repeat"
_PER_SEQUENCE = "one value per sequence, written on each of its frames (read row frame_start)"


def forward_rows(values: np.ndarray, n_frames: int) -> np.ndarray:
    """(n − k, ...) forward differences → (n, ...) rows: the last k rows repeat the last defined
    row; zeros when there is none."""
    values = np.asarray(values, dtype=np.float64)
    out = np.zeros((n_frames, *values.shape[1:]))
    m = values.shape[0]
    if m > 0:
        out[:m] = values
        out[m:] = values[-1]
    return out


def _fps(batch: MotionBatch) -> float:
    fps = float(batch.attrs.get("fps") or 0)
    if not fps > 0:
        raise InputError("the motion attrs have no frame rate (fps)")
    return fps


def _up_axis(batch: MotionBatch) -> str:
    """'y' or 'z' for kinetic energies (the sign of the up axis does not matter there)."""
    axis = str(batch.attrs.get("up_axis") or "y").lstrip("+-").lower()
    return axis if axis in ("y", "z") else "y"


def _extension(
    path: str, row_shape: tuple, dtype: type, attrs: tuple[str, ...], note: str | None = None
) -> ArraySpec:
    return ArraySpec(path, row_shape, dtype, required_attrs=attrs, extension=True, note=note)


_KINETIC_NOTE = "3 per joint; per sequence, repeated on its frames"


@register_family("kinematics")
class KinematicsFamily(MotionFamily):
    """Derivatives of joint positions, motion beats, kinetic features."""

    inputs = (source_array("positions"),)
    outputs = (
        _extension("velocity", ("J", 3), np.float32, ("units", "rows")),
        _extension("acceleration", ("J", 3), np.float32, ("units", "rows")),
        _extension("jerk", ("J", 3), np.float32, ("units", "rows")),
        _extension("motion_beats_mint", (), np.uint8, ("variant", "rule")),
        _extension("motion_beats_bailando", (), np.uint8, ("variant", "rule")),
        _extension(
            "kinetic_features", (None,), np.float32, ("mode", "layout", "rows"), _KINETIC_NOTE
        ),
        _extension("kinetic_features_corrected", (None,), np.float32, ("mode", "layout", "rows")),
    )

    def arrays(self, n_joints: int, settings: MotionSettings) -> list[ArraySpec]:
        joint = (n_joints, 3)
        return [
            ArraySpec(
                "velocity", joint, np.float32, {"units": "m/s", "rows": _FORWARD.format(k=1)}
            ),
            ArraySpec(
                "acceleration", joint, np.float32, {"units": "m/s^2", "rows": _FORWARD.format(k=2)}
            ),
            ArraySpec("jerk", joint, np.float32, {"units": "m/s^3", "rows": _FORWARD.format(k=3)}),
            ArraySpec(
                "motion_beats_mint",
                (),
                np.uint8,
                {
                    "variant": "mint (FACT/AIST++)",
                    "rule": f"strict local minima over ±{MINT_ORDER} frames of the summed joint "
                    "displacement arriving at frame t",
                    "values": "1 on motion-beat frames",
                },
            ),
            ArraySpec(
                "motion_beats_bailando",
                (),
                np.uint8,
                {
                    "variant": "bailando",
                    "rule": f"strict local minima of the mean joint displacement from t to t+1, "
                    f"Gaussian-smoothed (sigma {BAILANDO_SIGMA:g} frames)",
                    "values": "1 on motion-beat frames (t: the step from frame t to t+1)",
                },
            ),
            ArraySpec(
                "kinetic_features",
                (3 * n_joints,),
                np.float32,
                {
                    "mode": "parity (AIST++/Bailando code, acceleration precedence slip kept)",
                    "layout": "per joint: horizontal KE, vertical KE, energy expenditure",
                    "rows": _PER_SEQUENCE,
                },
            ),
            ArraySpec(
                "kinetic_features_corrected",
                (3 * n_joints,),
                np.float32,
                {
                    "mode": "corrected (acceleration (p[k+1] - 2p[k] + p[k-1]) / dt^2)",
                    "layout": "per joint: horizontal KE, vertical KE, energy expenditure",
                    "rows": _PER_SEQUENCE,
                },
            ),
        ]

    def compute(self, batch: MotionBatch, settings: MotionSettings) -> dict[str, np.ndarray]:
        positions = batch.arrays["positions"]
        fps, up = _fps(batch), _up_axis(batch)
        n_total, n_joints = positions.shape[:2]
        out = {
            "velocity": np.zeros((n_total, n_joints, 3)),
            "acceleration": np.zeros((n_total, n_joints, 3)),
            "jerk": np.zeros((n_total, n_joints, 3)),
            "motion_beats_mint": np.zeros(n_total, dtype=np.uint8),
            "motion_beats_bailando": np.zeros(n_total, dtype=np.uint8),
            "kinetic_features": np.zeros((n_total, 3 * n_joints)),
            "kinetic_features_corrected": np.zeros((n_total, 3 * n_joints)),
        }
        for part in batch.sequences():
            p = positions[part]
            n = p.shape[0]
            for k, name in enumerate(("velocity", "acceleration", "jerk"), start=1):
                diff = np.diff(p, n=k, axis=0) * fps**k if n > k else p[:0]
                out[name][part] = forward_rows(diff, n)
            if n >= 2:
                out["motion_beats_mint"][part][motion_beats_mint(p, MINT_ORDER)] = 1
                out["motion_beats_bailando"][part][motion_beats_bailando(p, BAILANDO_SIGMA)] = 1
            if n >= 3:
                for name, mode in (
                    ("kinetic_features", "parity"),
                    ("kinetic_features_corrected", "corrected"),
                ):
                    out[name][part] = kinetic_features(p, fps, mode=mode, up_axis=up)
        return out

    def config(self, settings: MotionSettings) -> dict[str, Any]:
        return {
            "derivatives": "forward differences x fps^k",
            "mint_order": MINT_ORDER,
            "bailando_sigma": BAILANDO_SIGMA,
            "kinetic_window": 2,
        }


@register_family("angular")
class AngularFamily(MotionFamily):
    """Angular velocity of each joint's local rotation, and the Laban weight effort."""

    inputs = (source_array("axis_angle"),)
    outputs = (
        _extension("angular_velocity", ("J", 3), np.float32, ("units", "rows")),
        _extension("weight_effort", (), np.float32, ("units", "rows")),
    )

    def arrays(self, n_joints: int, settings: MotionSettings) -> list[ArraySpec]:
        return [
            ArraySpec(
                "angular_velocity",
                (n_joints, 3),
                np.float32,
                {
                    "units": "rad/s",
                    "formula": "vector part of 2 dq conj(q), dq = (q[t+1] - q[t]) fps, local "
                    "rotations (parent frame)",
                    "rows": _FORWARD.format(k=1),
                },
            ),
            ArraySpec(
                "weight_effort",
                (),
                np.float32,
                {
                    "units": "rad/s",
                    "formula": "sum over joints of |angular_velocity| (Laban weight effort)",
                    "rows": _FORWARD.format(k=1),
                },
            ),
        ]

    def compute(self, batch: MotionBatch, settings: MotionSettings) -> dict[str, np.ndarray]:
        axis_angle = batch.arrays["axis_angle"]
        fps = _fps(batch)
        quat = axis_angle_to_quat(axis_angle)
        omega = np.zeros(axis_angle.shape)
        effort = np.zeros(axis_angle.shape[0])
        for part in batch.sequences():
            w = angular_velocity(quat[part], fps)
            n = quat[part].shape[0]
            omega[part] = forward_rows(w, n)
            effort[part] = forward_rows(np.linalg.norm(w, axis=-1).sum(axis=-1), n)
        return {"angular_velocity": omega, "weight_effort": effort}

    def config(self, settings: MotionSettings) -> dict[str, Any]:
        return {"angular_velocity": "2 dq conj(q), forward difference, sign-continuous"}


def _is_smpl24(skeleton: dict[str, Any]) -> bool:
    from dancedata.compute.smpl import SMPL_JOINTS

    joints = tuple(skeleton.get("joints") or ())
    return joints == SMPL_JOINTS or (skeleton.get("name") == "smpl24" and len(joints) == 24)


@register_family("geometric")
class GeometricFamily(MotionFamily):
    """The 32 geometric (Müller) features of SMPL-24 poses, per sequence."""

    inputs = (source_array("positions"),)
    outputs = (
        _extension(
            "geometric_features",
            (32,),
            np.float32,
            ("definition", "rows"),
            "SMPL-24 only; per sequence, repeated on its frames",
        ),
    )

    def arrays(self, n_joints: int, settings: MotionSettings) -> list[ArraySpec]:
        return [
            ArraySpec(
                "geometric_features",
                (32,),
                np.float32,
                {
                    "definition": "Müller et al. 2005 predicates as in the AIST++/Bailando "
                    "code, each averaged over frames 1..n-1",
                    "velocity_frame_time_s": GEOMETRIC_FRAME_TIME_S,
                    "rows": _PER_SEQUENCE,
                },
            )
        ]

    def compute(self, batch: MotionBatch, settings: MotionSettings) -> dict[str, np.ndarray]:
        skeleton = batch.attrs.get("skeleton") or {}
        if not _is_smpl24(skeleton):
            raise InputError(
                "the geometric family needs SMPL-24 joint positions (its predicates name SMPL "
                f"joints); this store's skeleton is {skeleton.get('name')!r} with "
                f"{len(skeleton.get('joints') or ())} joints: leave 'geometric' out"
            )
        positions = batch.arrays["positions"]
        out = np.zeros((positions.shape[0], 32))
        for part in batch.sequences():
            if part.stop - part.start >= 2:
                out[part] = geometric_features(positions[part], GEOMETRIC_FRAME_TIME_S)
        return {"geometric_features": out}

    def config(self, settings: MotionSettings) -> dict[str, Any]:
        return {"velocity_frame_time_s": GEOMETRIC_FRAME_TIME_S}
