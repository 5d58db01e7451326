"""Laban-effort distance between two motions: how differently they move, by effort.

Each motion is summarised by its efforts (``dancedata.compute.laban.effort_summary``: Time, Space,
Flow and Weight, each the mean over frames of the effort summed over joints). The distance is the
mean over efforts of the symmetric relative difference |a − b| / ((|a| + |b|) / 2): 0 for equal
efforts, 2 at most per effort, dimensionless, so efforts in m/s², m/s³ and rad/s weigh alike and
no reference scale is needed. An effort that is 0 in both motions contributes 0.
"""

from __future__ import annotations

from collections.abc import Mapping

import numpy as np

from dancedata.metrics.result import MetricResult

__all__ = ["laban_effort_distance", "laban_effort_distance_result"]


def laban_effort_distance(a: Mapping[str, float], b: Mapping[str, float]) -> float:
    """Mean over the efforts of |a − b| / ((|a| + |b|) / 2); both motions name the same efforts."""
    if set(a) != set(b) or not a:
        raise ValueError(f"the two motions' efforts differ: {sorted(a)} vs {sorted(b)}")
    terms = []
    for name in sorted(a):
        x, y = float(a[name]), float(b[name])
        scale = (abs(x) + abs(y)) / 2.0
        terms.append(0.0 if scale == 0.0 else abs(x - y) / scale)
    return float(np.mean(terms))


def laban_effort_distance_result(
    generated: list[Mapping[str, float]], reference: list[Mapping[str, float]], n_frames: int
) -> MetricResult:
    """The mean distance over pairs (generated[i], reference[i]) of the same music, named."""
    if len(generated) != len(reference):
        raise ValueError("need one reference summary per generated summary")
    values = [laban_effort_distance(g, r) for g, r in zip(generated, reference, strict=True)]
    efforts = sorted(generated[0]) if generated else []
    return MetricResult(
        "laban_effort_distance",
        float(np.mean(values)) if values else float("nan"),
        {
            "definition": "mean over efforts of |a-b| / ((|a|+|b|)/2), Larboulette & Gibet 2015 "
            "efforts",
            "efforts": efforts,
            "reduce": "mean_over_units",
        },
        len(values),
        int(n_frames),
    )
