"""Per-measure segmentation from tempo: pure arithmetic, no audio needed.

Frames per measure ``fpm = 60 / bpm × beats_per_measure × fps``. Measure k spans frames
``[floor(phase + k·fpm + 0.5), floor(phase + (k+1)·fpm + 0.5))`` (half-open, rounded to the
nearest frame), and only complete measures, those ending at or before the last frame, are kept.
``phase`` is the downbeat offset in frames.
"""

from __future__ import annotations

import math

import numpy as np


def frames_per_measure(bpm: float, fps: float, beats_per_measure: int = 4) -> float:
    """Frames in one measure: 60 / bpm × beats_per_measure × fps (fractional)."""
    if not (bpm > 0 and fps > 0 and beats_per_measure > 0):
        raise ValueError(
            f"bpm, fps and beats_per_measure must be positive ({bpm}, {fps}, {beats_per_measure})"
        )
    return 60.0 / bpm * beats_per_measure * fps


def measure_bounds(
    n_frames: int, bpm: float, fps: float, beats_per_measure: int = 4, phase: float = 0.0
) -> np.ndarray:
    """(M, 2) int64 half-open [start, stop) frame bounds of the complete measures."""
    fpm = frames_per_measure(bpm, fps, beats_per_measure)
    if n_frames <= 0:
        return np.zeros((0, 2), dtype=np.int64)
    # Upper bound on the count, then keep those whose stop fits and whose start is >= 0.
    k_max = int(math.ceil((n_frames - phase) / fpm)) + 1
    k = np.arange(max(k_max, 0), dtype=np.float64)
    starts = np.floor(phase + k * fpm + 0.5).astype(np.int64)
    stops = np.floor(phase + (k + 1) * fpm + 0.5).astype(np.int64)
    keep = (starts >= 0) & (stops <= n_frames) & (stops > starts)
    return np.stack([starts[keep], stops[keep]], axis=1)
