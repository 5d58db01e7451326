"""The value every metric returns: a number together with the convention that produced it.

docs/EXPERIMENTS.md §0.4 and §4.10: public implementations of "the same" metric differ in ways that
change the number (direction, σ, normalisation, frame ranges). So no metric here returns a bare
float: each returns a :class:`MetricResult` naming the metric, its convention (every parameter
that affects the number) and the sample size behind it.
"""

from __future__ import annotations

import math
from collections.abc import Iterable, Mapping
from dataclasses import dataclass, field
from typing import Any

import numpy as np

__all__ = ["MetricResult", "mean_over_units"]


@dataclass(frozen=True)
class MetricResult:
    """One metric value and how it was computed.

    Attributes:
        name: the metric's name in results records (``mse``, ``fid_k``, ``bas_mint``, ...;
            docs/EXPERIMENTS.md §5.5).
        value: the number (float64; NaN when undefined, e.g. no beats).
        convention: every parameter that affects ``value`` (JSON-serialisable), including the
            public implementation it follows (``"convention": "mint"``...).
        n_units: how many units (sequences, measures, clips, feature vectors) the value
            aggregates.
        n_frames: how many motion frames those units hold.
        details: diagnostics that do not change the value's meaning (e.g. the largest
            imaginary part dropped from a matrix square root, columns dropped).
    """

    name: str
    value: float
    convention: dict[str, Any]
    n_units: int
    n_frames: int
    details: dict[str, Any] = field(default_factory=dict)

    def as_dict(self) -> dict[str, Any]:
        return {
            "metric": self.name,
            "value": None if math.isnan(self.value) else float(self.value),
            "convention": dict(self.convention),
            "n_units": int(self.n_units),
            "n_frames": int(self.n_frames),
            "details": dict(self.details),
        }


def mean_over_units(
    name: str,
    values: Iterable[float],
    convention: Mapping[str, Any],
    n_frames: int,
    *,
    skip_nan: bool = False,
) -> MetricResult:
    """The mean of per-unit values (e.g. per-sequence beat scores) as a MetricResult.

    ``skip_nan``: leave undefined units out of the mean (their count goes into
    ``details["n_undefined"]``); otherwise one NaN makes the mean NaN. NaN for no units.
    """
    array = np.asarray(list(values), dtype=np.float64)
    undefined = int(np.isnan(array).sum())
    used = array[~np.isnan(array)] if skip_nan else array
    value = float(np.mean(used)) if used.size else float("nan")
    details = {"n_undefined": undefined} if undefined else {}
    return MetricResult(
        name,
        value,
        {**dict(convention), "reduce": "mean_over_units", "skip_nan": skip_nan},
        int(used.size),
        int(n_frames),
        details,
    )
