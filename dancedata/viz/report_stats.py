"""Value statistics of stored arrays for the report: NaN, Inf, out-of-range counts, histograms.

Counts (finite values, NaN, ±Inf, values outside the array's expected range, min, max, mean)
are exact: every row is read, one zarr chunk of rows at a time, so memory stays at one chunk.
Histograms are drawn from at most ``max_hist_rows`` rows taken at an even stride (all rows when
the array is smaller), and say how many rows they saw.

Expected ranges (:data:`EXPECTED_RANGES`) are what each array's recipe guarantees, so a value
outside is a defect, not an outlier. Each carries its reason; arrays without a guaranteed range
are only checked for NaN and Inf. AIST++ keypoints hold NaN where triangulation or detection
failed (docs/STORE.md), so NaN there is data; the report lists it all the same.
"""

from __future__ import annotations

import fnmatch
import math
from dataclasses import dataclass
from typing import Any

import numpy as np

# Slack on closed unit ranges: float32 rotation matrices and quaternions reach ±1 ± a few ulps.
UNIT_SLACK = 1e-4

# array-name pattern → (low, high, why); first match wins.
EXPECTED_RANGES: list[tuple[str, float, float, str]] = [
    ("audio/onset_peaks", 0, 1, "0/1 indicator"),
    ("audio/beats", 0, 1, "0/1 indicator"),
    ("audio/stems/*/onset_peaks", 0, 1, "0/1 indicator"),
    ("audio/onset_env", 0, math.inf, "onset strength is a rectified spectral flux, ≥ 0"),
    ("audio/stems/*/onset_env", 0, math.inf, "onset strength is a rectified spectral flux, ≥ 0"),
    ("audio/chroma_cens", 0, 1 + UNIT_SLACK, "CENS: non-negative, unit L2 norm per frame"),
    ("audio/nmfd_drums", 0, math.inf, "NMFD activations are non-negative"),
    ("motion/rotmat", -1 - UNIT_SLACK, 1 + UNIT_SLACK, "rotation matrix entries lie in [-1, 1]"),
    ("motion/quat", -1 - UNIT_SLACK, 1 + UNIT_SLACK, "unit quaternion components lie in [-1, 1]"),
    ("motion/rot6d", -1 - UNIT_SLACK, 1 + UNIT_SLACK, "columns of a rotation matrix, in [-1, 1]"),
    ("motion/euler", -math.pi - UNIT_SLACK, math.pi + UNIT_SLACK, "principal Euler angles, rad"),
    ("motion/det_scores", 0, 1, "detector scores are probabilities"),
    ("motion/*_mask", 0, 2, "mask codes 0 missing, 1 detected, 2 gap-filled"),
]


def expected_range(name: str) -> tuple[float, float, str] | None:
    """(low, high, reason) for array ``name``, or None when it has no guaranteed range."""
    for pattern, low, high, why in EXPECTED_RANGES:
        if fnmatch.fnmatchcase(name, pattern):
            return low, high, why
    return None


@dataclass
class ArrayStats:
    """Exact value counts of one array plus a (row-sampled) histogram of its finite values."""

    name: str
    shape: tuple[int, ...]
    dtype: str
    values: int = 0
    nan: int = 0
    inf: int = 0
    out_of_range: int = 0
    expected: tuple[float, float, str] | None = None
    minimum: float = math.nan
    maximum: float = math.nan
    mean: float = math.nan
    hist_counts: np.ndarray | None = None
    hist_edges: np.ndarray | None = None
    hist_rows: int = 0

    @property
    def flagged(self) -> bool:
        """True when the array has NaN, Inf or values outside its expected range."""
        return bool(self.nan or self.inf or self.out_of_range)

    def as_dict(self) -> dict[str, Any]:
        return {
            "name": self.name,
            "shape": list(self.shape),
            "dtype": self.dtype,
            "values": self.values,
            "nan": self.nan,
            "inf": self.inf,
            "out_of_range": self.out_of_range,
            "min": self.minimum,
            "max": self.maximum,
            "mean": self.mean,
        }


def block_counts(block: np.ndarray, expected: tuple[float, float, str] | None) -> dict[str, Any]:
    """Counts over one block of values: n, nan, inf, out_of_range (finite values outside the
    expected range), and finite sum, min, max (None when no value is finite).

    Reductions run on the block as stored (sum accumulated in float64); only a block that
    holds NaN or Inf is copied to drop them."""
    values = np.asarray(block).reshape(-1)
    nan = inf = 0
    if values.dtype.kind in "fc":
        n_finite = int(np.count_nonzero(np.isfinite(values)))
        if n_finite < values.size:
            nan = int(np.count_nonzero(np.isnan(values)))
            inf = values.size - n_finite - nan
            values = values[np.isfinite(values)]
    out = {
        "n": int(values.size) + nan + inf,
        "nan": nan,
        "inf": inf,
        "out_of_range": 0,
        "sum": float(values.sum(dtype=np.float64)),
        "finite": int(values.size),
        "min": float(values.min()) if values.size else None,
        "max": float(values.max()) if values.size else None,
    }
    if expected is not None and values.size:
        low, high, _ = expected
        out["out_of_range"] = int(np.count_nonzero(values < low) + np.count_nonzero(values > high))
    return out


def array_stats(array: Any, name: str, *, max_hist_rows: int = 20000, bins: int = 30) -> ArrayStats:
    """Stats of a zarr (or numpy) array of at least one dimension, read one chunk of rows
    (along axis 0) at a time."""
    shape = tuple(int(n) for n in array.shape)
    stats = ArrayStats(name=name, shape=shape, dtype=str(array.dtype))
    stats.expected = expected_range(name)
    rows = shape[0] if shape else 0
    step = int(getattr(array, "chunks", (8192,))[0] or 8192)
    stride = max(1, math.ceil(rows / max_hist_rows))
    total = finite = 0
    acc_sum = 0.0
    lo = hi = None
    samples: list[np.ndarray] = []
    for start in range(0, rows, step):
        block = np.asarray(array[start : start + step])
        c = block_counts(block, stats.expected)
        total += c["n"]
        stats.nan += c["nan"]
        stats.inf += c["inf"]
        stats.out_of_range += c["out_of_range"]
        finite += c["finite"]
        acc_sum += c["sum"]
        if c["min"] is not None:
            lo = c["min"] if lo is None else min(lo, c["min"])
            hi = c["max"] if hi is None else max(hi, c["max"])
        first = (-start) % stride  # rows start, start+stride, ... of the whole array
        picked = block[first::stride]
        if picked.size:
            samples.append(picked.reshape(-1))
    stats.values = total
    if finite:
        stats.minimum, stats.maximum, stats.mean = float(lo), float(hi), acc_sum / finite
    if samples:
        sample = np.concatenate(samples).astype(np.float64)
        sample = sample[np.isfinite(sample)]
        stats.hist_rows = len(range(0, rows, stride))
        if sample.size:
            low, high = float(sample.min()), float(sample.max())
            if high <= low:
                high = low + 1.0
            stats.hist_counts, stats.hist_edges = np.histogram(sample, bins=bins, range=(low, high))
    return stats
