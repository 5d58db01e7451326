"""Diversity (docs/METRICS.md; Bailando ``calculate_avg_distance``, FACT Dist_k / Dist_g).

    Div(F̃) = 2 / (n(n−1)) · Σ_{i<j} ‖f̃_i − f̃_j‖₂

the mean Euclidean distance over all unordered pairs of feature vectors, after z-scoring by the
*reference* set's statistics (the same normalisation as FID; Bailando normalises both sets by
the ground truth's mean and std + 1e−10).
"""

from __future__ import annotations

import numpy as np
from scipy.spatial.distance import pdist

from dancedata.metrics.frechet import reference_normalization
from dancedata.metrics.result import MetricResult

__all__ = ["diversity"]


def diversity(
    features: np.ndarray,
    reference: np.ndarray | None = None,
    *,
    name: str = "diversity",
    std_eps: float = 1e-10,
    n_frames: int = 0,
) -> MetricResult:
    """Mean pairwise distance of (n, d) ``features``; z-scored by ``reference`` (n_ref, d) when
    given (pass the features themselves for the ground truth's own diversity). NaN for n < 2."""
    x = np.asarray(features, dtype=np.float64)
    if x.ndim != 2:
        raise ValueError(f"features must be (samples, dims), got {x.shape}")
    if reference is not None:
        mean, std = reference_normalization(reference, std_eps)
        x = (x - mean) / std
    value = float(np.mean(pdist(x))) if x.shape[0] >= 2 else float("nan")
    convention = {
        "distance": "euclidean",
        "pairs": "all_unordered",
        "normalize": "reference_zscore" if reference is not None else "none",
        "std_eps": std_eps if reference is not None else None,
    }
    return MetricResult(name, value, convention, int(x.shape[0]), int(n_frames))
