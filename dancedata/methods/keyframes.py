"""Keyframe selection per measure (docs/EXPERIMENTS.md §2): pure functions, batched over measures.

Strategies (spec ids): ``even``; ``peaks:onset``, ``peaks:stems``, ``peaks:nmfd`` (peak-picked
from a 1-d curve: the full-mix onset envelope, the weighted stem onsets, the weighted NMFD
activation); ``dp`` (Roberts' minimax DP over the measure's 75-d Euler rows). Every measure
keeps its first and last frame; N counts them (``n_counts_edges``, the default reading).

Single-measure helpers (:func:`even_keyframes`, :func:`peak_keyframes`, :func:`dp_keyframes`)
return a :class:`KeyframeSet`; the ``*_batch`` functions take (M, L, ...) arrays of M measures
of one length L, which is how the pipeline calls them (measures grouped by length).

Every [CHOICE] of the spec is a field of :class:`KeyframeParams`, recorded with the results.
"""

from __future__ import annotations

from dataclasses import asdict, dataclass, field
from typing import Any

import numpy as np

from dancedata.errors import InputError
from dancedata.methods.keyframes_dp import DP_COMBINES, DP_DISTANCES, dp_keyframes_batch
from dancedata.methods.keyframes_peaks import (
    DP,
    EVEN,
    FILL_RULES,
    KEYFRAME_SOURCES,
    peak_keyframes_batch,
)

STRATEGIES: tuple[str, ...] = ("even", "peaks:onset", "peaks:stems", "peaks:nmfd", "dp")
# Short names accepted on the command line.
STRATEGY_ALIASES: dict[str, str] = {
    "onset": "peaks:onset",
    "stems": "peaks:stems",
    "nmfd": "peaks:nmfd",
}
PEAK_SOURCES: tuple[str, ...] = ("local_max", "onset_detect")
EULER_BRANCHES: tuple[str, ...] = ("principal", "continuous")
AUDIO_SCOPES: tuple[str, ...] = ("track",)
EVEN_ROUNDING = "floor(k*(L-1)/(N-1) + 0.5)"
DEFAULT_STEM_WEIGHTS = {"drums": 1.0, "bass": 1.0, "vocals": 1.0, "other": 1.0}
DEFAULT_NMFD_WEIGHTS = {"kick": 1.0, "snare": 1.0, "hihat": 1.0}


def canonical_strategy(name: str) -> str:
    """``onset`` → ``peaks:onset`` etc.; InputError for an unknown strategy."""
    strategy = STRATEGY_ALIASES.get(name.strip(), name.strip())
    if strategy not in STRATEGIES:
        known = ", ".join([*STRATEGIES, *STRATEGY_ALIASES])
        raise InputError(f"unknown keyframe strategy {name!r}; known: {known}")
    return strategy


@dataclass(frozen=True)
class KeyframeParams:
    """The [CHOICE] parameters of docs/EXPERIMENTS.md §2 with their defaults (§9, rows 1–10).

    ``guard`` is the edge guard G in frames (60 fps: 6 frames = 0.1 s). ``stem_weights`` and
    ``nmfd_weights`` weight the curves of ``peaks:stems`` / ``peaks:nmfd``; ``normalize`` divides
    each component curve by its maximum over the sequence first. ``audio_scope`` is ``track``
    (stored per-track features sliced per measure; ``measure`` is not implemented).
    """

    n_counts_edges: bool = True
    guard: int = 6
    peak_source: str = "local_max"
    fill: str = "adjacent_max_sum"
    stem_weights: dict[str, float] = field(default_factory=lambda: dict(DEFAULT_STEM_WEIGHTS))
    nmfd_weights: dict[str, float] = field(default_factory=lambda: dict(DEFAULT_NMFD_WEIGHTS))
    normalize: bool = False
    audio_scope: str = "track"
    dp_distance: str = "vertical"
    combine: str = "max"
    euler_branch: str = "principal"

    def __post_init__(self) -> None:
        checks = (
            ("peak source", self.peak_source, PEAK_SOURCES),
            ("fill rule", self.fill, FILL_RULES),
            ("audio scope", self.audio_scope, AUDIO_SCOPES),
            ("DP distance", self.dp_distance, DP_DISTANCES),
            ("DP combine", self.combine, DP_COMBINES),
            ("Euler branch", self.euler_branch, EULER_BRANCHES),
        )
        for what, value, known in checks:
            if value not in known:
                raise InputError(f"unknown {what} {value!r}; known: {', '.join(known)}")
        if self.guard < 0:
            raise InputError(f"edge guard must be ≥ 0 frames, got {self.guard}")
        unknown = sorted(set(self.stem_weights) - set(DEFAULT_STEM_WEIGHTS))
        if unknown:
            raise InputError(f"unknown stem(s) {unknown}; stems are {list(DEFAULT_STEM_WEIGHTS)}")
        unknown = sorted(set(self.nmfd_weights) - set(DEFAULT_NMFD_WEIGHTS))
        if unknown:
            raise InputError(
                f"unknown NMFD component(s) {unknown}; components are {list(DEFAULT_NMFD_WEIGHTS)}"
            )

    def total_keyframes(self, n: int) -> int:
        """Frames selected per measure for the requested N (N + 2 when N excludes the edges)."""
        return n if self.n_counts_edges else n + 2

    def for_strategy(self, strategy: str) -> dict[str, Any]:
        """The parameters that change ``strategy``'s keyframes (what its run id hashes)."""
        common = {"n_counts_edges": self.n_counts_edges}
        if strategy == "even":
            return {**common, "rounding": EVEN_ROUNDING}
        if strategy == "dp":
            return {
                **common,
                "dp_distance": self.dp_distance,
                "combine": self.combine,
                "euler_branch": self.euler_branch,
                "tie_break": "smallest j",
            }
        peaks = {
            **common,
            "guard": self.guard,
            "fill": self.fill,
            "audio_scope": self.audio_scope,
            "peak_detector": "scipy.signal.find_peaks (no thresholds)",
            "ranking": "curve value descending, ties to the smaller frame",
        }
        if strategy == "peaks:onset":
            return {**peaks, "peak_source": self.peak_source}
        if strategy == "peaks:stems":
            return {**peaks, "stem_weights": self.stem_weights, "normalize": self.normalize}
        return {**peaks, "nmfd_weights": self.nmfd_weights, "normalize": self.normalize}

    def as_dict(self) -> dict[str, Any]:
        return asdict(self)


@dataclass(frozen=True)
class KeyframeSet:
    """The keyframes of one measure: N strictly increasing local indices (first 0, last L−1),
    the source of each (``edge``/``even``/``peak``/``fill``/``dp``) and its score (curve value
    for peaks and fills, segment error for dp, NaN otherwise)."""

    indices: np.ndarray
    source: tuple[str, ...]
    score: np.ndarray


def _check_lengths(length: int, n: int) -> None:
    if n < 2:
        raise InputError(f"need at least 2 keyframes (first and last frame), got {n}")
    if length < n:
        raise InputError(f"a measure of {length} frames cannot hold {n} keyframes")


def even_indices(length: int, n: int) -> np.ndarray:
    """(N,) int64 ``floor(k·(L−1)/(N−1) + 0.5)``, k = 0 … N−1 (docs/EXPERIMENTS.md §2.2)."""
    _check_lengths(length, n)
    k = np.arange(n, dtype=np.float64)
    return np.floor(k * (length - 1) / (n - 1) + 0.5).astype(np.int64)


def even_keyframes(length: int, n: int) -> KeyframeSet:
    """Evenly spaced keyframes of a measure of ``length`` frames."""
    idx = even_indices(length, n)
    source = ("edge",) + ("even",) * (n - 2) + ("edge",)
    return KeyframeSet(idx, source, np.full(n, np.nan))


def _as_set(indices: np.ndarray, sources: np.ndarray, scores: np.ndarray) -> KeyframeSet:
    return KeyframeSet(
        indices.astype(np.int64),
        tuple(KEYFRAME_SOURCES[int(s)] for s in sources),
        scores.astype(np.float64),
    )


def peak_keyframes(
    curve: np.ndarray,
    n: int,
    guard: int = 6,
    fill: str = "adjacent_max_sum",
    candidates: np.ndarray | None = None,
) -> KeyframeSet:
    """Peak-picked keyframes of one measure's 1-d curve (L,) (see
    :mod:`dancedata.methods.keyframes_peaks`)."""
    curve = np.asarray(curve, dtype=np.float64)
    _check_lengths(curve.shape[-1], n)
    cand = None if candidates is None else np.asarray(candidates, dtype=bool)[None]
    idx, src, score = peak_keyframes_batch(curve[None], n, guard, fill, cand)
    return _as_set(idx[0], src[0], score[0])


def dp_keyframes(
    x: np.ndarray, n: int, distance: str = "vertical", combine: str = "max"
) -> tuple[KeyframeSet, float]:
    """DP keyframes of one measure's (L, D) curve, and the DP cost C_N(L−1)."""
    x = np.asarray(x, dtype=np.float64)
    _check_lengths(x.shape[0], n)
    idx, cost, score = dp_keyframes_batch(x[None], [n], distance, combine)[n]
    return _as_set(idx[0], np.full(n, DP), score[0]), float(cost[0])


def even_batch(m: int, length: int, n: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``even`` for M measures of one length: (indices, source codes, scores) as (M, N)."""
    idx = np.broadcast_to(even_indices(length, n), (m, n)).copy()
    src = np.full((m, n), EVEN, dtype=np.int8)
    src[:, [0, -1]] = 0
    return idx, src, np.full((m, n), np.nan)
