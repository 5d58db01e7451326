"""Beats and phrases as units, motion-to-music beat alignment and re-timing (pure arithmetic).

* **Beats** lie on the same tempo grid as the measures (``compute.measures``): beat j at the
  exact frame ``phase + j·fpb`` with ``fpb = 60 / bpm × fps``, rounded to the nearest frame;
  beat j is number ``j mod beats_per_measure`` of measure ``j // beats_per_measure`` and a
  downbeat when that number is 0. Only beats inside the sequence are kept.
* **Phrases** are runs of ``phrase_measures`` consecutive complete measures (4 or 8 in dance
  music), starting at measure 0; only complete phrases are kept.
* **Alignment** (ChoreoGraph, Au et al. 2022; mint's motion beats): a motion segment between two
  motion beats is matched to the span between two music beats, and **re-timed** onto it: the
  frames between the motion beats are resampled (linear for positions, SLERP for rotations) so
  that the first motion beat lands on the first music beat and the last on the last.
* **ChoreoGraph segments**: the music is cut into segments of about ``segment_s`` seconds that
  start and end on music beats, and each gets the motion span between the motion beats nearest
  to its ends.
"""

from __future__ import annotations

import math

import numpy as np

from dancedata.compute.resample import resample_linear, resample_quaternions

__all__ = [
    "beat_grid",
    "choreograph_segments",
    "nearest_beats",
    "phrase_bounds",
    "retime",
    "retime_positions",
    "retime_quaternions",
]


def beat_grid(
    n_frames: int, bpm: float, fps: float, beats_per_measure: int = 4, phase: float = 0.0
) -> dict[str, np.ndarray]:
    """The tempo grid's beats inside [0, n_frames): ``beat`` (index j ≥ 0 from the phase),
    ``frame`` (nearest frame), ``time_exact`` (s, unrounded), ``measure``, ``beat_in_measure``,
    ``downbeat`` (bool). Beats before frame 0 (negative j) are left out."""
    if not all(math.isfinite(v) and v > 0 for v in (bpm, fps)) or beats_per_measure < 1:
        raise ValueError(f"bpm and fps must be positive and finite ({bpm}, {fps})")
    fpb = 60.0 / bpm * fps
    if fpb < 1.0:
        raise ValueError(f"{bpm} BPM at {fps} fps puts beats less than one frame apart")
    if n_frames <= 0:
        j = np.zeros(0, dtype=np.int64)
    else:
        j_max = int(math.floor((n_frames - 0.5 - phase) / fpb))
        j_min = max(0, int(math.ceil((-0.5 - phase) / fpb)))
        j = np.arange(j_min, max(j_min, j_max + 1), dtype=np.int64)
    exact = phase + j * fpb
    frame = np.floor(exact + 0.5).astype(np.int64)
    keep = (frame >= 0) & (frame < n_frames)
    j, exact, frame = j[keep], exact[keep], frame[keep]
    number = j % beats_per_measure
    return {
        "beat": j,
        "frame": frame,
        "time_exact": exact / fps,
        "measure": j // beats_per_measure,
        "beat_in_measure": number,
        "downbeat": number == 0,
    }


def phrase_bounds(measure_bounds: np.ndarray, phrase_measures: int) -> np.ndarray:
    """(P, 4) int64 rows [first measure, last measure + 1, frame_start, frame_stop) of the
    complete phrases of ``phrase_measures`` consecutive measures, from (M, 2) measure bounds."""
    if phrase_measures < 1:
        raise ValueError("a phrase has at least one measure")
    bounds = np.asarray(measure_bounds, dtype=np.int64).reshape(-1, 2)
    n = len(bounds) // phrase_measures
    first = np.arange(n) * phrase_measures
    last = first + phrase_measures
    if n == 0:
        return np.zeros((0, 4), dtype=np.int64)
    return np.stack([first, last, bounds[first, 0], bounds[last - 1, 1]], axis=1)


def nearest_beats(points: np.ndarray, beats: np.ndarray) -> np.ndarray:
    """For each frame in ``points``, the nearest frame in ``beats`` (ties go to the earlier)."""
    beats = np.sort(np.asarray(beats, dtype=np.int64))
    if beats.size == 0:
        raise ValueError("no beats to align to")
    points = np.asarray(points, dtype=np.int64)
    idx = np.clip(np.searchsorted(beats, points), 1, max(1, beats.size - 1))
    left = beats[idx - 1]
    right = beats[np.minimum(idx, beats.size - 1)]
    return np.where(np.abs(points - left) <= np.abs(right - points), left, right)


def _warp_positions(src: tuple[int, int], dst: tuple[int, int]) -> np.ndarray:
    """Fractional source frames for each destination frame dst0..dst1 (inclusive)."""
    (s0, s1), (d0, d1) = src, dst
    if not (s1 > s0 and d1 > d0):
        raise ValueError(f"spans must be increasing: source {src}, destination {dst}")
    return s0 + (np.arange(d0, d1 + 1) - d0) * (s1 - s0) / (d1 - d0)


def retime(values: np.ndarray, src: tuple[int, int], dst: tuple[int, int]) -> np.ndarray:
    """Frames src0..src1 (inclusive) of ``values`` (F, ...) resampled linearly onto
    dst1 − dst0 + 1 frames: src0 lands on the first, src1 on the last (a re-tempo by
    (src1 − src0) / (dst1 − dst0))."""
    return resample_linear(np.asarray(values, dtype=np.float64), _warp_positions(src, dst))


def retime_positions(
    positions: np.ndarray, src: tuple[int, int], dst: tuple[int, int]
) -> np.ndarray:
    """:func:`retime` for joint positions (F, J, 3): linear in time."""
    return retime(positions, src, dst)


def retime_quaternions(quat: np.ndarray, src: tuple[int, int], dst: tuple[int, int]) -> np.ndarray:
    """:func:`retime` for unit quaternions (F, J, 4) wxyz: SLERP between neighbouring frames."""
    return resample_quaternions(np.asarray(quat, dtype=np.float64), _warp_positions(src, dst))


def choreograph_segments(
    music_beats: np.ndarray, motion_beats: np.ndarray, fps: float, segment_s: float = 4.0
) -> dict[str, np.ndarray]:
    """Music segments of about ``segment_s`` seconds from beat to beat, each with its
    beat-aligned motion span.

    Starting at the first music beat, each segment ends on the music beat nearest to
    ``start + segment_s·fps`` (at least one beat later); the motion span runs from the motion
    beat nearest the segment's start to the one nearest its end. Returns columns
    ``music_start``, ``music_stop``, ``motion_start``, ``motion_stop`` (frames),
    ``n_music_beats`` and ``tempo_ratio`` (motion span / music span: the factor :func:`retime`
    applies; NaN for an empty motion span).
    """
    beats = np.unique(np.asarray(music_beats, dtype=np.int64))
    target = segment_s * fps
    if not (math.isfinite(target) and target >= 1):
        raise ValueError(f"segment_s × fps must be at least one frame, got {target}")
    starts: list[int] = []
    stops: list[int] = []
    counts: list[int] = []
    i = 0
    while i < beats.size - 1:
        want = beats[i] + target
        j = i + 1 + int(np.argmin(np.abs(beats[i + 1 :] - want)))
        if beats[j] - beats[i] < 0.5 * target:  # the track ends before half a segment
            break
        starts.append(int(beats[i]))
        stops.append(int(beats[j]))
        counts.append(j - i)
        i = j
    music_start = np.asarray(starts, dtype=np.int64)
    music_stop = np.asarray(stops, dtype=np.int64)
    if len(motion_beats):
        motion_start = nearest_beats(music_start, motion_beats)
        motion_stop = nearest_beats(music_stop, motion_beats)
    else:
        motion_start = motion_stop = np.full(music_start.shape, -1, dtype=np.int64)
    span = (motion_stop - motion_start).astype(np.float64)
    with np.errstate(divide="ignore", invalid="ignore"):
        ratio = np.where(span > 0, span / (music_stop - music_start), np.nan)
    return {
        "music_start": music_start,
        "music_stop": music_stop,
        "motion_start": motion_start,
        "motion_stop": motion_stop,
        "n_music_beats": np.asarray(counts, dtype=np.int64),
        "tempo_ratio": ratio,
    }
