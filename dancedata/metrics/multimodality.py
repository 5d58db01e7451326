"""Multimodality (docs/METRICS.md, "Multimodality"): how different several generations for the
same music are.

    MM = mean over groups g (music pieces) of  2 / (n_g(n_g−1)) · Σ_{i<j} ‖f̃_i − f̃_j‖₂

over the n_g ≥ 2 generations of group g, f̃ = features z-scored by the reference (ground
truth) statistics, std + 1e−10, as diversity is (FACT's and Bailando's
``calculate_avg_distance``). Lee et al. (2019) average over random combinations of five
generations; every pair is equally likely in such a combination, so the mean over all pairs is
the expected value of theirs, without the sampling noise.
"""

from __future__ import annotations

from collections.abc import Mapping

import numpy as np
from scipy.spatial.distance import pdist

from dancedata.metrics.frechet import reference_normalization
from dancedata.metrics.result import MetricResult

__all__ = ["multimodality"]


def multimodality(
    groups: Mapping[str, np.ndarray],
    reference: np.ndarray | None = None,
    *,
    name: str = "multimodality",
    std_eps: float = 1e-10,
    n_frames: int = 0,
) -> MetricResult:
    """Mean over ``groups`` (group → (n_g, d) features of its generations) of the mean
    pairwise Euclidean distance, z-scored by ``reference`` (n_ref, d) when given. Groups with
    fewer than 2 generations are left out (named in ``details["single"]``); NaN when none is
    left."""
    mean = std = None
    if reference is not None:
        mean, std = reference_normalization(reference, std_eps)
    per_group: dict[str, float] = {}
    single: list[str] = []
    for key, features in groups.items():
        x = np.asarray(features, dtype=np.float64)
        if x.ndim != 2:
            raise ValueError(f"group {key}: features must be (generations, dims), got {x.shape}")
        if x.shape[0] < 2:
            single.append(key)
            continue
        if mean is not None:
            x = (x - mean) / std
        per_group[key] = float(np.mean(pdist(x)))
    value = float(np.mean(list(per_group.values()))) if per_group else float("nan")
    convention = {
        "distance": "euclidean",
        "pairs": "all_unordered_within_group",
        "reduce": "mean_over_groups",
        "normalize": "reference_zscore" if reference is not None else "none",
        "std_eps": std_eps if reference is not None else None,
    }
    details: dict[str, object] = {
        "n_groups": len(per_group),
        "generations_per_group": sorted({int(np.shape(g)[0]) for g in groups.values()}),
    }
    if single:
        details["single"] = sorted(single)
    n_units = sum(int(np.shape(groups[k])[0]) for k in per_group)
    return MetricResult(name, value, convention, n_units, int(n_frames), details)
