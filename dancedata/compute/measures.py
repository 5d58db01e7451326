"""Per-measure segmentation from tempo: pure arithmetic, no audio needed.

Frames per measure ``fpm = 60 / bpm × beats_per_measure × fps``. Measure k spans frames
``[floor(phase + k·fpm + 0.5), floor(phase + (k+1)·fpm + 0.5))`` (half-open, rounded to the
nearest frame), and only complete measures, those ending at or before the last frame, are kept.
``phase`` is the downbeat offset in frames. The bounds are whole frames; the exact (unrounded)
boundaries ``phase + k·fpm`` come from :func:`measure_grid`.
"""

from __future__ import annotations

import math

import numpy as np

# Beyond this many frames float64 can no longer place measure boundaries to the frame.
_MAX_PHASE = 1e12


def frames_per_measure(bpm: float, fps: float, beats_per_measure: int = 4) -> float:
    """Frames in one measure: 60 / bpm × beats_per_measure × fps (fractional)."""
    if not all(math.isfinite(v) and v > 0 for v in (bpm, fps, beats_per_measure)):
        raise ValueError(
            "bpm, fps and beats_per_measure must be positive finite numbers "
            f"({bpm}, {fps}, {beats_per_measure})"
        )
    fpm = 60.0 / bpm * beats_per_measure * fps
    if not math.isfinite(fpm):
        raise ValueError(f"{bpm} BPM at {fps} fps gives no finite measure length")
    if fpm < 1.0:
        raise ValueError(
            f"a measure of {beats_per_measure} beats at {bpm} BPM lasts {fpm:.3g} frames at "
            f"{fps} fps: less than one frame (wrong tempo or fps?)"
        )
    return fpm


def measure_bounds(
    n_frames: int, bpm: float, fps: float, beats_per_measure: int = 4, phase: float = 0.0
) -> np.ndarray:
    """(M, 2) int64 half-open [start, stop) frame bounds of the complete measures."""
    return measure_grid(n_frames, bpm, fps, beats_per_measure, phase)[0]


def measure_grid(
    n_frames: int, bpm: float, fps: float, beats_per_measure: int = 4, phase: float = 0.0
) -> tuple[np.ndarray, np.ndarray]:
    """The complete measures: (M, 2) int64 [start, stop) frame bounds (rounded to the nearest
    frame) and (M, 2) float64 exact [start, stop) in frames, ``phase + k·fpm`` before rounding
    (divide by fps for seconds)."""
    fpm = frames_per_measure(bpm, fps, beats_per_measure)
    if not (math.isfinite(phase) and abs(phase) <= _MAX_PHASE):
        raise ValueError(f"phase must be a number of frames within ±{_MAX_PHASE:g}, got {phase}")
    if n_frames <= 0 or fpm > n_frames + 1:  # no room for one complete measure
        return np.zeros((0, 2), dtype=np.int64), np.zeros((0, 2), dtype=np.float64)
    # Candidate measures k_min..k_max (a margin of one each side), then keep those whose start
    # is >= 0 and whose stop fits: the work is bounded by n_frames / fpm whatever the phase.
    k_min = max(0, math.floor((-phase - 0.5) / fpm) - 1)
    k_max = int(math.ceil((n_frames - phase) / fpm)) + 1
    k = np.arange(k_min, max(k_max, k_min), dtype=np.float64)
    exact_starts = phase + k * fpm
    exact_stops = phase + (k + 1) * fpm
    starts = np.floor(exact_starts + 0.5).astype(np.int64)
    stops = np.floor(exact_stops + 0.5).astype(np.int64)
    keep = (starts >= 0) & (stops <= n_frames) & (stops > starts)
    return (
        np.stack([starts[keep], stops[keep]], axis=1),
        np.stack([exact_starts[keep], exact_stops[keep]], axis=1),
    )
