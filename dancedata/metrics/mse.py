"""Reconstruction MSE (docs/METRICS.md; the thesis's Eq. 2.8): space, wrapping and reduction.

    MSE = 1/(N·J) · Σ_n Σ_j ‖x_n^j − x̂_n^j‖²

N = frames (keyframes included), J = blocks per frame, ‖·‖² = sum of squares within a block.

Spaces (the row layouts the store's views and the in-betweeners produce):

* ``euler75`` (default): (F, 75) ``thesis_euler_75`` rows, J = 25 three-vectors: root
  translation (m) and 24 Euler triples (rad). Same numbers as
  :func:`dancedata.metrics.reconstruction_error.mse_euler75` for ``pooled``.
* ``euler72``: the same rows with the translation left out, J = 24.
* ``rotmat``: (F, 225) ``fact_motion_225`` rows; the 6 padding zeros ignored, J = 25 blocks
  (translation, then 24 rotation matrices of 9 entries).
* ``axis_angle``: (F, 75) rows of translation + 24 axis-angle triples (rad), J = 25.

``wrap`` (Euler spaces only) wraps each angle difference to (−π, π] first. Reductions:
``pooled`` (one sum over all frames of all units / (frames · J)), ``measure_mean`` (mean of
per-unit MSEs) and ``sequence_mean`` (pooled within each sequence, then the mean over
sequences; needs ``groups``).
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Literal

import numpy as np

from dancedata.metrics.result import MetricResult

__all__ = ["MSE_SPACES", "mse", "wrap_angle"]

MseSpace = Literal["euler75", "euler72", "rotmat", "axis_angle"]
MseReduce = Literal["pooled", "measure_mean", "sequence_mean"]

# space -> (row width, first used column, blocks J, first angle column or None)
MSE_SPACES: dict[str, tuple[int, int, int, int | None]] = {
    "euler75": (75, 0, 25, 3),
    "euler72": (75, 3, 24, 3),
    "rotmat": (225, 6, 25, None),
    "axis_angle": (75, 0, 25, None),
}


def wrap_angle(delta: np.ndarray) -> np.ndarray:
    """Angle differences (rad) wrapped to (−π, π]."""
    return np.pi - np.mod(np.pi - delta, 2.0 * np.pi)


def _unit_sums(truth: np.ndarray, recon: np.ndarray, space: str, wrap: bool) -> tuple[float, int]:
    """Sum of squared errors over one unit's used columns, and its frame count."""
    width, first, _, angle_from = MSE_SPACES[space]
    x = np.asarray(truth, dtype=np.float64)
    y = np.asarray(recon, dtype=np.float64)
    if x.shape != y.shape or x.ndim != 2 or x.shape[1] != width:
        raise ValueError(
            f"mse[{space}] needs two (frames, {width}) arrays, got {x.shape} and {y.shape}"
        )
    diff = (y - x)[:, first:]
    if wrap:
        start = angle_from - first  # type: ignore[operator]
        diff = np.concatenate([diff[:, :start], wrap_angle(diff[:, start:])], axis=1)
    return float(np.sum(diff**2)), int(x.shape[0])


def mse(
    truth: Sequence[np.ndarray],
    recon: Sequence[np.ndarray],
    *,
    space: MseSpace = "euler75",
    wrap: bool = False,
    reduce: MseReduce = "pooled",
    groups: Sequence[str] | None = None,
) -> MetricResult:
    """Reconstruction MSE over units (measures or sequences).

    Args:
        truth, recon: one (F_u, D) array per unit, ground truth and reconstruction, same
            shapes pairwise; D as ``space`` says (75 or 225).
        space: row layout and block count J (module docstring).
        wrap: wrap angle differences to (−π, π] (``euler75``/``euler72`` only).
        reduce: ``pooled``, ``measure_mean`` or ``sequence_mean``.
        groups: the sequence id of each unit (``sequence_mean`` only).

    Returns:
        ``mse`` with convention {space, J, wrap, reduce}; n_units = units, n_frames = frames.
    """
    if space not in MSE_SPACES:
        raise ValueError(f"mse space must be one of {sorted(MSE_SPACES)}, got {space!r}")
    if reduce not in ("pooled", "measure_mean", "sequence_mean"):
        raise ValueError(f"mse reduce must be pooled, measure_mean or sequence_mean: {reduce!r}")
    joints = MSE_SPACES[space][2]
    if wrap and MSE_SPACES[space][3] is None:
        raise ValueError(f"wrap applies to Euler angles only, not to {space}")
    if len(truth) != len(recon):
        raise ValueError(f"{len(truth)} ground-truth units but {len(recon)} reconstructions")
    if len(truth) == 0:
        raise ValueError("mse over zero units")
    sums, frames = zip(
        *(_unit_sums(t, r, space, wrap) for t, r in zip(truth, recon, strict=True)), strict=True
    )
    sums_a = np.asarray(sums)
    frames_a = np.asarray(frames, dtype=np.float64)
    if np.any(frames_a == 0):
        raise ValueError("mse over a unit of zero frames")
    if reduce == "pooled":
        value = float(sums_a.sum() / (frames_a.sum() * joints))
    elif reduce == "measure_mean":
        value = float(np.mean(sums_a / (frames_a * joints)))
    else:
        if groups is None or len(groups) != len(truth):
            raise ValueError("mse reduce='sequence_mean' needs one group (seq id) per unit")
        keys = list(dict.fromkeys(groups))
        index = np.array([keys.index(g) for g in groups])
        per_seq = np.bincount(index, sums_a) / (np.bincount(index, frames_a) * joints)
        value = float(per_seq.mean())
    convention = {"space": space, "J": joints, "wrap": wrap, "reduce": reduce}
    return MetricResult("mse", value, convention, len(truth), int(frames_a.sum()))
