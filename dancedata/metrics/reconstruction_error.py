"""Reconstruction MSE of docs/EXPERIMENTS.md §4.1 in its default convention, one named function.

    MSE = 1/(N·J) · Σ_n Σ_j ‖x_n^j − x̂_n^j‖²          (000 Eq. 2.8)

with N the frames of every evaluated measure (keyframes included, error 0), and, in the
``euler75`` space, J = 25 three-vectors per frame: the root translation (m) and 24 Euler
triples (rad, the store's order), ‖·‖² the sum of the 3 squared components. Angle differences
are raw (principal branch minus principal branch) unless ``wrap``; then each difference is
wrapped to (−π, π]. ``pooled``: one sum over all frames divided by frames × J.

This is the minimal form the keyframe tests need; the metrics layer may supersede it.
"""

from __future__ import annotations

import numpy as np

from dancedata.errors import InputError


def mse_convention(wrap: bool = False) -> str:
    """The name recorded with every value: space, J, wrapping, reduction."""
    return f"mse[euler75,J=25,{'wrapped' if wrap else 'raw'},pooled]"


def mse_euler75(truth: np.ndarray, recon: np.ndarray, wrap: bool = False) -> float:
    """Pooled MSE between (F, 75) ground-truth and reconstructed ``thesis_euler_75`` rows.

    Args:
        truth, recon: (F, 75) arrays (trans m + 24 × 3 Euler rad); F pooled over measures.
        wrap: wrap angle differences (columns 3 …) to (−π, π] first (spec option
            ``mse_wrap``); translation differences are never wrapped.

    Returns:
        Σ over frames and the 25 three-vectors of the squared norm, / (F · 25).
    """
    x = np.asarray(truth, dtype=np.float64)
    y = np.asarray(recon, dtype=np.float64)
    if x.shape != y.shape or x.ndim != 2 or x.shape[1] != 75:
        raise InputError(f"MSE needs two (frames, 75) arrays, got {x.shape} and {y.shape}")
    if x.shape[0] == 0:
        raise InputError("MSE over zero frames")
    diff = y - x
    if wrap:
        angles = diff[:, 3:]
        wrapped = np.pi - np.mod(np.pi - angles, 2.0 * np.pi)  # (−π, π]
        diff = np.concatenate([diff[:, :3], wrapped], axis=1)
    joints = 25
    return float(np.sum(diff**2) / (x.shape[0] * joints))
