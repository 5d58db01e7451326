"""Beat metrics (docs/METRICS.md, "Beat scores"), each under its own name; they give different
numbers.

Per-sequence functions (positions in, one float out); :func:`mean_over_units` averages them over
sequences. Frames are motion frames; music beats are frame indices at the motion frame rate
(the store's ``audio/beats`` one-hot, see :func:`beat_frames`).

* ``bas_mint`` — motion → music, higher is better (mint ``calculate_beat_scores.py``): motion
  beats = strict minima over ±``order`` frames of the summed joint displacement; mean over motion
  beats of exp(−d²/(2σ²)), d = frames to the nearest music beat, σ = 3; 0 without motion beats.
  Which music beats count is named (``beats``: the motion's span, or the whole track as mint
  does for generated motion).
* ``bas_bailando`` — music → motion, higher is better (Bailando ``beat_align_score.py``): motion
  beats = minima of the mean joint displacement smoothed by a Gaussian (σ = 5); music beats
  before frame F−1 only; mean over music beats of exp(−d²/(2·9)).
* ``bas_msd_motion2music`` / ``bas_msd_music2motion`` — ChoreoGraph (004 §4.2.2), lower is
  better: motion beats = ``scipy.signal.find_peaks`` of the negated mean joint speed at 20 fps;
  mean of the squared frame distance to the nearest beat of the other kind; NaN if either set is
  empty.
* ``beat_coverage`` = B_k / B_m, ``beat_hit_rate`` = B_a / B_k (Lee et al. 2019) and
  ``beat_accuracy`` = B_a / B_m (ChoreoMaster), B_a from :func:`greedy_beat_matching`.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Literal

import numpy as np

from dancedata.compute.motion_features import (
    beat_align_score_bailando,
    beat_align_score_mint,
    motion_beats_bailando,
    motion_beats_mint,
)

__all__ = [
    "BAS_BEATS",
    "BasBeats",
    "BeatCounts",
    "bas_bailando",
    "bas_mint",
    "bas_msd",
    "beat_counts",
    "beat_frames",
    "decimate_beats",
    "greedy_beat_matching",
    "motion_beats_choreograph",
]


BasBeats = Literal["motion_span", "whole_track_mint"]
BAS_BEATS: tuple[str, ...] = ("motion_span", "whole_track_mint")


def beat_frames(onehot: np.ndarray, n_frames: int | None = None) -> np.ndarray:
    """Frame indices where a per-frame beat flag is set (> 0.5), optionally only those
    < ``n_frames``."""
    flags = np.asarray(onehot).reshape(-1)
    if n_frames is not None:
        flags = flags[:n_frames]
    return np.flatnonzero(flags > 0.5)


def _positions(positions: np.ndarray) -> np.ndarray:
    p = np.asarray(positions, dtype=np.float64)
    if p.ndim != 3 or p.shape[2] != 3 or p.shape[0] < 2:
        raise ValueError(f"need joint positions (F >= 2, J, 3), got {p.shape}")
    return p


def bas_mint(
    positions: np.ndarray,
    music_beats: np.ndarray,
    *,
    sigma: float = 3.0,
    order: int = 10,
    skip_frames: int = 0,
    beats: BasBeats = "motion_span",
) -> float:
    """mint's beat-alignment score of one sequence (module docstring).

    Args:
        positions: (F, J, 3) joint positions at 60 fps (order 10 is "10 for 60FPS").
        music_beats: music-beat frame indices (frame 0 = the motion's first frame).
        sigma: the Gaussian's σ in frames.
        order: argrelextrema order (frames each side).
        skip_frames: drop beats of both kinds before this frame after detection (mint scores
            generated motion on frames 120:).
        beats: which music beats a motion beat may match (:data:`BAS_BEATS`):
            ``"motion_span"`` those < F (mint's path for real data, which cuts the audio
            features to the motion's length); ``"whole_track_mint"`` every given beat, also
            after the last motion frame (mint's path for generated motion, which keeps the
            whole track's beats, so a motion beat near the end can match a later music beat).
    """
    if beats not in BAS_BEATS:
        raise ValueError(f"beats must be one of {', '.join(BAS_BEATS)}, got {beats!r}")
    p = _positions(positions)
    motion = motion_beats_mint(p, order=order)
    music = np.asarray(music_beats, dtype=np.int64)
    keep = music >= skip_frames
    if beats == "motion_span":
        keep &= music < p.shape[0]
    music = music[keep]
    motion = motion[motion >= skip_frames]
    if motion.size and not music.size:
        return float("nan")
    return beat_align_score_mint(music, motion, sigma=sigma)


def bas_bailando(
    positions: np.ndarray,
    music_beats: np.ndarray,
    *,
    sigma: float = 3.0,
    smoothing_sigma: float = 5.0,
) -> float:
    """Bailando's beat-alignment score of one sequence: mean over the music beats before frame
    F−1 of exp(−d²/(2σ²)) to the nearest motion beat. NaN without music beats, 0 without motion
    beats (where Bailando's ``np.min`` of an empty array would raise)."""
    p = _positions(positions)
    motion = motion_beats_bailando(p, sigma=smoothing_sigma)
    return beat_align_score_bailando(
        np.asarray(music_beats), motion, sigma=sigma, n_frames=p.shape[0] - 1
    )


def decimate_beats(beats: np.ndarray, step: int) -> np.ndarray:
    """Beat frames at a rate ``step`` times lower: floor(i/step + 0.5), duplicates merged."""
    beats = np.asarray(beats, dtype=np.int64)
    return np.unique(np.floor(beats / step + 0.5).astype(np.int64))


def motion_beats_choreograph(positions: np.ndarray, fps: float) -> np.ndarray:
    """ChoreoGraph motion beats: local minima of the mean joint speed (``find_peaks`` of the
    negated speed, no height/distance/prominence). Speed index t is the step t → t+1."""
    from scipy.signal import find_peaks  # here: scipy.signal takes ~0.5 s to import

    p = _positions(positions)
    speed = np.linalg.norm((p[1:] - p[:-1]) * fps, axis=-1).mean(axis=1)
    return find_peaks(-speed)[0]


def _mean_sq_nearest(points: np.ndarray, targets: np.ndarray) -> float:
    if points.size == 0 or targets.size == 0:
        return float("nan")
    d = np.abs(points[:, None].astype(np.float64) - targets[None, :].astype(np.float64))
    return float(np.mean(d.min(axis=1) ** 2))


def bas_msd(motion_beats: np.ndarray, music_beats: np.ndarray) -> tuple[float, float]:
    """ChoreoGraph's two mean squared distances (frames²), lower is better:
    (motion2music: each motion beat to its nearest music beat, music2motion: the reverse).
    NaN when either set is empty."""
    motion = np.asarray(motion_beats).reshape(-1)
    music = np.asarray(music_beats).reshape(-1)
    return _mean_sq_nearest(motion, music), _mean_sq_nearest(music, motion)


def greedy_beat_matching(
    motion_beats: np.ndarray, music_beats: np.ndarray, tol: int
) -> list[tuple[int, int]]:
    """One-to-one beat matching: each motion beat, in time order, takes the nearest music beat
    not yet taken within ±``tol`` frames (a tie goes to the earlier music beat). Returns the
    (motion beat, music beat) pairs."""
    music = sorted(int(m) for m in np.asarray(music_beats).reshape(-1))
    taken = [False] * len(music)
    pairs: list[tuple[int, int]] = []
    for b in sorted(int(b) for b in np.asarray(motion_beats).reshape(-1)):
        best = None
        for i, m in enumerate(music):
            if taken[i] or abs(m - b) > tol:
                continue
            if best is None or abs(m - b) < abs(music[best] - b):
                best = i
        if best is not None:
            taken[best] = True
            pairs.append((b, music[best]))
    return pairs


@dataclass(frozen=True)
class BeatCounts:
    """Counts behind coverage, hit rate and accuracy: B_k motion beats, B_m music beats, B_a
    aligned (matched) beats."""

    motion: int
    music: int
    aligned: int

    @property
    def coverage(self) -> float:
        """B_k / B_m (NaN without music beats)."""
        return self.motion / self.music if self.music else float("nan")

    @property
    def hit_rate(self) -> float:
        """B_a / B_k (NaN without motion beats)."""
        return self.aligned / self.motion if self.motion else float("nan")

    @property
    def accuracy(self) -> float:
        """B_a / B_m (NaN without music beats)."""
        return self.aligned / self.music if self.music else float("nan")


def beat_counts(
    positions: np.ndarray,
    music_beats: np.ndarray,
    *,
    tol: int = 12,
    detector: Literal["mint", "bailando"] = "mint",
    order: int = 10,
) -> BeatCounts:
    """B_k, B_m and B_a of one sequence: motion beats by ``detector`` (mint: argrelextrema
    order ``order``; bailando: smoothed minima), music beats < F, greedy matching within
    ±``tol`` frames (12 = 0.2 s at 60 fps)."""
    p = _positions(positions)
    if detector == "mint":
        motion = motion_beats_mint(p, order=order)
    elif detector == "bailando":
        motion = motion_beats_bailando(p)
    else:
        raise ValueError(f"beat detector must be mint or bailando, got {detector!r}")
    music = np.asarray(music_beats, dtype=np.int64)
    music = music[music < p.shape[0]]
    aligned = len(greedy_beat_matching(motion, music, tol))
    return BeatCounts(int(motion.size), int(music.size), aligned)
