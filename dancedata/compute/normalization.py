"""Per-column mean and standard deviation of a training split, and applying them.

The statistics are accumulated in float64 per block of rows with Chan et al.'s pairwise update
(count, mean, sum of squared deviations M2), so they equal ``np.mean``/``np.std`` of all the
rows concatenated to rounding, in any block order, without holding the rows at once.
Normalisation is (x − mean) / std; a column whose std is below :data:`STD_FLOOR` (constant over
the split) is divided by 1 instead, so it maps to 0 and is restored exactly.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

__all__ = ["STD_FLOOR", "Moments", "denormalize", "normalize"]

STD_FLOOR = 1e-8


@dataclass(frozen=True)
class Moments:
    """Running moments of rows of D columns: count, per-column mean and M2 (float64)."""

    count: int
    mean: np.ndarray
    m2: np.ndarray

    @classmethod
    def empty(cls, n_columns: int) -> Moments:
        return cls(0, np.zeros(n_columns), np.zeros(n_columns))

    @classmethod
    def of(cls, rows: np.ndarray, weights: np.ndarray | None = None) -> Moments:
        """Moments of (N, ...) rows, columns flattened; ``weights`` (N,) whole numbers count a
        row that many times (a song's audio row under several training sequences)."""
        x = np.asarray(rows, dtype=np.float64).reshape(len(rows), -1)
        w = np.ones(len(x)) if weights is None else np.asarray(weights, dtype=np.float64)
        count = int(w.sum())
        if count == 0:
            return cls.empty(x.shape[1])
        mean = (w[:, None] * x).sum(axis=0) / count
        return cls(count, mean, (w[:, None] * (x - mean) ** 2).sum(axis=0))

    def add(self, other: Moments) -> Moments:
        """The moments of both sets of rows (Chan, Golub & LeVeque's pairwise formula)."""
        if other.count == 0:
            return self
        if self.count == 0:
            return other
        n = self.count + other.count
        delta = other.mean - self.mean
        mean = self.mean + delta * (other.count / n)
        m2 = self.m2 + other.m2 + delta**2 * (self.count * other.count / n)
        return Moments(n, mean, m2)

    @property
    def std(self) -> np.ndarray:
        """Population standard deviation (ddof 0) per column; NaN without rows."""
        if self.count == 0:
            return np.full(self.mean.shape, np.nan)
        return np.sqrt(np.maximum(self.m2 / self.count, 0.0))


def _scale(std: np.ndarray) -> np.ndarray:
    std = np.asarray(std, dtype=np.float64)
    return np.where(std < STD_FLOOR, 1.0, std)


def normalize(x: np.ndarray, mean: np.ndarray, std: np.ndarray) -> np.ndarray:
    """(x − mean) / std, broadcast over leading axes; constant columns divided by 1."""
    return ((np.asarray(x, dtype=np.float64) - mean) / _scale(std)).astype(np.float32)


def denormalize(z: np.ndarray, mean: np.ndarray, std: np.ndarray) -> np.ndarray:
    """The inverse of :func:`normalize` (for exporting a model's normalised output)."""
    return (np.asarray(z, dtype=np.float64) * _scale(std) + mean).astype(np.float32)
