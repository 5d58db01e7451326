"""Counts the report adds to ``dancedata info``: per tempo, per dancer, and durations.

Pure functions over the rows of the sequences and music tables (lists of dicts)."""

from __future__ import annotations

from collections import Counter
from typing import Any

import numpy as np


def _label(value: Any) -> str:
    if value is None:
        return "(none)"
    if isinstance(value, float):
        return f"{value:g}"
    return str(value)


def count_by(rows: list[dict[str, Any]], column: str) -> dict[str, int]:
    """Rows per value of ``column`` (missing column or None → "(none)"), sorted by value."""
    counts = Counter(_label(r.get(column)) for r in rows)

    def key(item: tuple[str, int]) -> tuple[int, float, str]:
        try:
            return (0, float(item[0]), item[0])
        except ValueError:
            return (1, 0.0, item[0])

    return dict(sorted(counts.items(), key=key))


def duration_summary(seconds: list[float]) -> dict[str, float | int]:
    """n, total, min, median, mean and max of a list of durations in seconds."""
    if not seconds:
        return {"n": 0}
    values = np.asarray(seconds, dtype=np.float64)
    return {
        "n": int(values.size),
        "total_s": float(values.sum()),
        "min_s": float(values.min()),
        "median_s": float(np.median(values)),
        "mean_s": float(values.mean()),
        "max_s": float(values.max()),
    }


def sequence_durations(sequences: list[dict[str, Any]]) -> list[float]:
    """Each sequence's motion duration, n_frames / fps seconds."""
    return [float(s["n_frames"]) / float(s["fps"]) for s in sequences if s.get("fps")]


def duration_histogram(seconds: list[float], bins: int = 12) -> tuple[np.ndarray, np.ndarray]:
    """np.histogram of durations over [min, max] (a 1-s wide range when all are equal)."""
    values = np.asarray(seconds, dtype=np.float64)
    if values.size == 0:
        return np.zeros(0, np.int64), np.zeros(1)
    low, high = float(values.min()), float(values.max())
    if high <= low:
        low, high = low - 0.5, high + 0.5
    return np.histogram(values, bins=bins, range=(low, high))
