"""Detect and repair root-orientation flips in generated motion (pure; rotations as axis-angle).

Networks that predict the root (hip) rotation frame by frame sometimes turn the whole body by
about 180° from one frame to the next and back a few frames later; the genre-LSTM study fixes
these by hand. No dancer turns the pelvis by more than a fraction of that in one frame (at 30
fps, 90° per frame is 2700°/s), so a frame-to-frame root rotation above ``threshold_deg`` is a
flip, not motion.

Repair works frame by frame on the already repaired previous frame R'ₜ₋₁: when the step
Rₜ R'ₜ₋₁⁻¹ exceeds the threshold, the frame is a flip. The flip F is estimated against the
orientation the motion would have reached at constant angular velocity,
Pₜ = (R'ₜ₋₁ R'ₜ₋₂⁻¹) R'ₜ₋₁ (Pₜ = R'ₜ₋₁ at frame 1): F is the half turn about the axis of
Dₜ = Rₜ Pₜ⁻¹, and the frame is replaced by R'ₜ = F⁻¹ Rₜ. The same F is removed from the
following frames while that keeps them continuous (the output is still flipped); once the raw
frame is continuous with the repaired one again (it flipped back), nothing more is changed.
Motion inside a flip is kept (only the half turn is removed). A planted half turn is removed
exactly (to rounding) when the root turns at constant angular velocity around the flip's first
frame; otherwise the estimated axis tilts by the order of one frame's change of angular
velocity, the same tilt for the whole flipped run.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.spatial.transform import Rotation

__all__ = ["FlipRepair", "repair_root_flips", "root_step_angles"]


@dataclass(frozen=True)
class FlipRepair:
    """Repaired root rotations and what was found.

    Attributes:
        root: (F, 3) repaired root axis-angle (radians).
        frames: every frame that was turned back by a half turn (all frames of each flipped
            run: each differs from the repaired frame before it by more than the threshold).
        angles_deg: the raw step angle from the repaired previous frame at each of those
            frames (degrees; about 180 where a flip starts).
        threshold_deg: the threshold used.
    """

    root: np.ndarray
    frames: np.ndarray
    angles_deg: np.ndarray
    threshold_deg: float

    @property
    def runs(self) -> list[tuple[int, int]]:
        """[first, last + 1) of each run of consecutive repaired frames."""
        if not self.frames.size:
            return []
        breaks = np.flatnonzero(np.diff(self.frames) > 1)
        starts = np.r_[self.frames[0], self.frames[breaks + 1]]
        stops = np.r_[self.frames[breaks], self.frames[-1]] + 1
        return list(zip(starts.tolist(), stops.tolist(), strict=True))

    def summary(self) -> str:
        """One line for the console and the manifest."""
        if not self.frames.size:
            return f"no root flips above {self.threshold_deg:g}° per frame"
        runs = self.runs
        shown = ", ".join(f"{a}-{b - 1}" if b - a > 1 else f"{a}" for a, b in runs[:6])
        return (
            f"{len(runs)} root flip(s) above {self.threshold_deg:g}° per frame repaired, "
            f"{self.frames.size} frame(s) turned back (frames {shown}"
            f"{', ...' if len(runs) > 6 else ''}; largest step {self.angles_deg.max():.0f}°)"
        )


def root_step_angles(root_axis_angle: np.ndarray) -> np.ndarray:
    """(F−1,) angle in degrees of the rotation from each frame's root orientation to the next."""
    rot = Rotation.from_rotvec(np.asarray(root_axis_angle, dtype=np.float64).reshape(-1, 3))
    if len(rot) < 2:
        return np.zeros(0)
    return np.degrees((rot[1:] * rot[:-1].inv()).magnitude())


def repair_root_flips(root_axis_angle: np.ndarray, threshold_deg: float = 90.0) -> FlipRepair:
    """Remove half-turn flips of the root orientation (F, 3) axis-angle; see the module text."""
    if not (np.isfinite(threshold_deg) and 0 < threshold_deg < 180):
        raise ValueError(f"threshold_deg must be in (0, 180), got {threshold_deg}")
    rotvec = np.asarray(root_axis_angle, dtype=np.float64).reshape(-1, 3)
    if not np.all(np.isfinite(rotvec)):
        raise ValueError("root rotations must be finite")
    out = rotvec.copy()
    if len(rotvec) < 2:
        return FlipRepair(out, np.zeros(0, np.int64), np.zeros(0), float(threshold_deg))
    rot = Rotation.from_rotvec(rotvec)
    threshold = np.radians(threshold_deg)
    prev = rot[0]
    before: Rotation | None = None  # the repaired frame before ``prev`` (constant velocity)
    active: Rotation | None = None  # the half turn being removed while the output is flipped
    frames: list[int] = []
    angles: list[float] = []
    for t in range(1, len(rotvec)):
        raw_step = (rot[t] * prev.inv()).magnitude()
        if active is not None and (active.inv() * rot[t] * prev.inv()).magnitude() <= threshold:
            current = active.inv() * rot[t]  # still flipped: remove the same half turn
        elif raw_step <= threshold:
            active, current = None, rot[t]  # flipped back, or never flipped
        else:  # a new flip: a half turn about the axis of the step from the prediction
            predicted = prev if before is None else prev * before.inv() * prev
            step = rot[t] * predicted.inv()
            if step.magnitude() < 1e-12:  # (cannot happen above the threshold; guard anyway)
                step = rot[t] * prev.inv()
            active = Rotation.from_rotvec(np.pi * step.as_rotvec() / step.magnitude())
            current = active.inv() * rot[t]
        if active is not None:
            out[t] = current.as_rotvec()
            frames.append(t)
            angles.append(float(np.degrees(raw_step)))
        before, prev = prev, current
    return FlipRepair(
        out, np.asarray(frames, dtype=np.int64), np.asarray(angles), float(threshold_deg)
    )
