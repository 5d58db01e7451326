"""Laban efforts and higher angular derivatives, computed on request.

* ``laban`` (positions): the Time, Space and Flow efforts of Larboulette & Gibet (2015) per
  joint and summed over joints, each over a centred window of :data:`LABAN_WINDOW_S` seconds
  (formulas in :mod:`dancedata.compute.laban`). The Weight effort is the ``angular`` family's
  ``weight_effort`` (summed joint angular speed, the genre thesis' definition).
* ``angular_derivatives`` (axis_angle): angular acceleration (rad/s²) and angular jerk (rad/s³)
  of each joint's local rotation, and their magnitudes summed over joints.

Rows follow the motion arrays' rule (one row per frame): windowed efforts are defined on every
frame; a derivative of order k fills the last k rows of a sequence with its last defined row.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from dancedata.compute.laban import (
    SPACE_FLOOR_M,
    laban_flow,
    laban_space,
    laban_time,
    window_frames,
)
from dancedata.compute.motion_features import angular_velocity
from dancedata.compute.rotations import axis_angle_to_quat
from dancedata.featurize.families.motion_base import (
    ArraySpec,
    MotionBatch,
    MotionFamily,
    MotionSettings,
)
from dancedata.featurize.families.motion_kinematics import _FORWARD, _extension, _fps, forward_rows
from dancedata.featurize.family import register_family
from dancedata.featurize.source_arrays import source_array

__all__ = ["AngularDerivativesFamily", "LabanFamily", "LABAN_WINDOW_S"]

LABAN_WINDOW_S = 1.0  # seconds: about one measure of dance music, centred on each frame
_WINDOWED = "one value per frame: the effort over the window centred on it (clipped at the ends)"
_EFFORTS = (
    ("time", "m/s^2", "mean |acceleration| over the window (Larboulette & Gibet 2015, Time)"),
    (
        "space",
        "1",
        "path length / max(net displacement, 1 mm) over the window, >= 1 "
        "(Larboulette & Gibet 2015, Space)",
    ),
    ("flow", "m/s^3", "mean |jerk| over the window (Larboulette & Gibet 2015, Flow)"),
)


@register_family("laban")
class LabanFamily(MotionFamily):
    """Time, Space and Flow efforts of joint trajectories, per joint and summed."""

    inputs = (source_array("positions"),)
    outputs = tuple(
        spec
        for name, _, _ in _EFFORTS
        for spec in (
            _extension(f"laban_{name}", ("J",), np.float32, ("units", "formula", "window_s")),
            _extension(f"laban_{name}_sum", (), np.float32, ("units", "formula", "window_s")),
        )
    )

    def arrays(self, n_joints: int, settings: MotionSettings) -> list[ArraySpec]:
        specs = []
        for name, units, formula in _EFFORTS:
            attrs = {"units": units, "formula": formula, "window_s": LABAN_WINDOW_S}
            attrs["rows"] = _WINDOWED
            specs.append(ArraySpec(f"laban_{name}", (n_joints,), np.float32, attrs))
            summed = {**attrs, "formula": f"sum over joints of laban_{name}"}
            specs.append(ArraySpec(f"laban_{name}_sum", (), np.float32, summed))
        return specs

    def compute(self, batch: MotionBatch, settings: MotionSettings) -> dict[str, np.ndarray]:
        positions = batch.arrays["positions"]
        fps = _fps(batch)
        window = window_frames(LABAN_WINDOW_S, fps)
        n_total, n_joints = positions.shape[:2]
        out = {f"laban_{name}": np.zeros((n_total, n_joints)) for name, _, _ in _EFFORTS}
        for part in batch.sequences():
            p = positions[part]
            out["laban_time"][part] = laban_time(p, fps, window=window)
            out["laban_space"][part] = laban_space(p, window=window)
            out["laban_flow"][part] = laban_flow(p, fps, window=window)
        for name, _, _ in _EFFORTS:
            out[f"laban_{name}_sum"] = out[f"laban_{name}"].sum(axis=1)
        return out

    def config(self, settings: MotionSettings) -> dict[str, Any]:
        return {
            "efforts": "Larboulette & Gibet 2015 time/space/flow, joint weights 1",
            "window_s": LABAN_WINDOW_S,
            "space_floor_m": SPACE_FLOOR_M,
        }


@register_family("angular_derivatives")
class AngularDerivativesFamily(MotionFamily):
    """Angular acceleration and jerk of each joint's local rotation, and their sums."""

    inputs = (source_array("axis_angle"),)
    outputs = (
        _extension("angular_acceleration", ("J", 3), np.float32, ("units", "rows")),
        _extension("angular_jerk", ("J", 3), np.float32, ("units", "rows")),
        _extension("angular_acceleration_sum", (), np.float32, ("units", "rows")),
        _extension("angular_jerk_sum", (), np.float32, ("units", "rows")),
    )

    def arrays(self, n_joints: int, settings: MotionSettings) -> list[ArraySpec]:
        joint = (n_joints, 3)
        formula = "forward differences of angular_velocity (2 dq conj(q)) x fps^k"
        return [
            ArraySpec(
                "angular_acceleration",
                joint,
                np.float32,
                {"units": "rad/s^2", "formula": formula, "rows": _FORWARD.format(k=2)},
            ),
            ArraySpec(
                "angular_jerk",
                joint,
                np.float32,
                {"units": "rad/s^3", "formula": formula, "rows": _FORWARD.format(k=3)},
            ),
            ArraySpec(
                "angular_acceleration_sum",
                (),
                np.float32,
                {
                    "units": "rad/s^2",
                    "formula": "sum over joints of |angular_acceleration|",
                    "rows": _FORWARD.format(k=2),
                },
            ),
            ArraySpec(
                "angular_jerk_sum",
                (),
                np.float32,
                {
                    "units": "rad/s^3",
                    "formula": "sum over joints of |angular_jerk|",
                    "rows": _FORWARD.format(k=3),
                },
            ),
        ]

    def compute(self, batch: MotionBatch, settings: MotionSettings) -> dict[str, np.ndarray]:
        axis_angle = batch.arrays["axis_angle"]
        fps = _fps(batch)
        quat = axis_angle_to_quat(axis_angle)
        out = {
            "angular_acceleration": np.zeros(axis_angle.shape),
            "angular_jerk": np.zeros(axis_angle.shape),
            "angular_acceleration_sum": np.zeros(axis_angle.shape[0]),
            "angular_jerk_sum": np.zeros(axis_angle.shape[0]),
        }
        for part in batch.sequences():
            omega = angular_velocity(quat[part], fps)
            n = quat[part].shape[0]
            for k, name in ((1, "angular_acceleration"), (2, "angular_jerk")):
                d = np.diff(omega, n=k, axis=0) * fps**k if omega.shape[0] > k else omega[:0]
                out[name][part] = forward_rows(d, n)
                out[f"{name}_sum"][part] = forward_rows(np.linalg.norm(d, axis=-1).sum(-1), n)
        return out

    def config(self, settings: MotionSettings) -> dict[str, Any]:
        return {"angular_derivatives": "forward differences of 2 dq conj(q) x fps^k"}
