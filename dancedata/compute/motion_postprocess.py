"""Post-processing of generated motion (pure): root-flip repair, then zero-phase smoothing.

A network's output often turns the whole body by a half turn for a few frames (root flips) and
jitters. :func:`postprocess_motion` applies, in this order (repair first: a low-pass filter
would smear a flip over its neighbours instead of removing it):

1. hip-flip repair (:func:`dancedata.compute.hip_flips.repair_root_flips`) of the root joint's
   rotation (joint 0), when asked;
2. a zero-phase Butterworth low-pass (:mod:`dancedata.compute.smoothing`, scipy ``butter`` +
   ``sosfiltfilt``, ``order`` per pass, so the effective order is 2·order and the gain at the
   cutoff is 1/2) of every joint's rotation on sign-continuous unit quaternions, renormalised
   (:func:`~dancedata.compute.smoothing.smooth_axis_angle`), of the root translation per axis,
   and of joint positions per coordinate, when a cutoff is given.

:func:`postprocess_config` is the record of what was done (the manifest's ``postprocess``).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from dancedata.compute.hip_flips import FlipRepair, repair_root_flips
from dancedata.compute.smoothing import butterworth_lowpass, smooth_axis_angle

__all__ = ["PostprocessResult", "postprocess_config", "postprocess_motion"]


@dataclass(frozen=True)
class PostprocessResult:
    """The post-processed arrays (None where none was given) and the flip repair found."""

    axis_angle: np.ndarray | None
    trans: np.ndarray | None
    positions: np.ndarray | None
    flips: FlipRepair | None


def postprocess_config(
    smooth_cutoff_hz: float | None, smooth_order: int, repair_flips: bool, flip_threshold_deg: float
) -> dict[str, object]:
    """What :func:`postprocess_motion` does with these settings, named (for the manifest)."""
    smoothing: dict[str, object] | None = None
    if smooth_cutoff_hz is not None:
        smoothing = {
            "filter": "butterworth low-pass, zero phase (scipy butter + sosfiltfilt)",
            "cutoff_hz": smooth_cutoff_hz,
            "order": smooth_order,
            "effective_order": 2 * smooth_order,
            "gain_at_cutoff": 0.5,
            "padding": "odd extension, scipy default length (shorter clips: n - 1)",
            "rotations": "unit quaternions wxyz, sign-continuous in time, each component "
            "filtered, renormalised",
            "translation": "each axis filtered (metres)",
            "positions": "each coordinate filtered (metres)",
        }
    repair: dict[str, object] | None = None
    if repair_flips:
        repair = {
            "joint": 0,
            "threshold_deg_per_frame": flip_threshold_deg,
            "method": "half turn about the step from the constant-velocity prediction removed "
            "while the output stays flipped (dancedata.compute.hip_flips)",
        }
    return {"order_of_steps": ["repair_hip_flips", "smooth"], "hip_flips": repair,
            "smoothing": smoothing}  # fmt: skip


def postprocess_motion(
    axis_angle: np.ndarray | None,
    trans: np.ndarray | None,
    positions: np.ndarray | None,
    fps: float,
    smooth_cutoff_hz: float | None = None,
    smooth_order: int = 2,
    repair_flips: bool = False,
    flip_threshold_deg: float = 90.0,
) -> PostprocessResult:
    """Repair root flips of (F, J, 3) ``axis_angle`` (radians) and/or low-pass it, the (F, 3)
    ``trans`` and the (F, J, 3) ``positions`` (metres) sampled at ``fps``; see the module text.
    ValueError when flips are to be repaired without rotations, or for a bad cutoff."""
    flips = None
    if repair_flips:
        if axis_angle is None:
            raise ValueError("hip-flip repair needs joint rotations; the motion has positions only")
        flips = repair_root_flips(axis_angle[:, 0], flip_threshold_deg)
        axis_angle = np.array(axis_angle, dtype=np.float64)
        axis_angle[:, 0] = flips.root
    if smooth_cutoff_hz is not None:
        if axis_angle is not None:
            axis_angle = smooth_axis_angle(axis_angle, fps, smooth_cutoff_hz, smooth_order)
        if trans is not None:
            trans = butterworth_lowpass(trans, fps, smooth_cutoff_hz, smooth_order)
        if positions is not None:
            positions = butterworth_lowpass(positions, fps, smooth_cutoff_hz, smooth_order)
    return PostprocessResult(axis_angle, trans, positions, flips)
