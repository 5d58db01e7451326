"""Peak-picked keyframes from a 1-d curve per measure (docs/EXPERIMENTS.md §2.3), vectorised.

Every function takes a batch of measures of one length L as an (M, L) array of curve values
(onset strength, weighted stem onsets, weighted NMFD activation: any finite float) and treats the
rows independently; there is no loop over measures, only over the ≤ N − 2 fill steps.

The steps, all deterministic:

1. edges ``{0, L−1}`` are always kept (source ``edge``);
2. candidates are strict local maxima as ``scipy.signal.find_peaks(c)`` finds them with no
   thresholds (a flat top gives its middle index, rounded down; the ends are never peaks), or a
   given candidate mask (the stored ``onset_detect`` peaks);
3. the edge guard drops candidates ``p < G`` and ``p > L−1−G``;
4. the remaining candidates are ranked by ``c[p]`` descending, ties to the smaller index, and
   the first ``N − 2`` are kept (source ``peak``);
5. while fewer than N are selected, one frame is inserted by the fill rule (source ``fill``):
   ``adjacent_max_sum`` (default) takes, among adjacent selected pairs (a, b) with b − a ≥ 2,
   the pair with the largest ``c[a] + c[b]`` (ties: larger gap, then smaller a) and inserts
   ``floor((a + b) / 2)``; ``top2_midpoint`` (the seed's literal wording) inserts the midpoint
   of the two selected frames with the highest c (ties: smaller index), falling back to
   ``adjacent_max_sum`` for that step when the midpoint is already selected.
"""

from __future__ import annotations

import numpy as np

from dancedata.errors import InputError

# Source codes of the selected frames; KEYFRAME_SOURCES[code] is the name in the keyframes table.
EDGE, EVEN, PEAK, FILL, DP = 0, 1, 2, 3, 4
KEYFRAME_SOURCES: tuple[str, ...] = ("edge", "even", "peak", "fill", "dp")
FILL_RULES: tuple[str, ...] = ("adjacent_max_sum", "top2_midpoint")


def local_maxima(curves: np.ndarray) -> np.ndarray:
    """(M, L) bool: the peaks ``scipy.signal.find_peaks(row)`` returns for every row.

    A peak is a run of equal values (length ≥ 1) with a strictly smaller neighbour on both
    sides; it is reported at the run's middle index, rounded down. Runs touching either end are
    never peaks, exactly as scipy's ``_local_maxima_1d``.
    """
    c = np.asarray(curves)
    if c.ndim != 2:
        raise ValueError(f"curves must be (measures, frames), got shape {c.shape}")
    m, length = c.shape
    out = np.zeros((m, length), dtype=bool)
    if length < 3:
        return out
    equal_next = c[:, 1:] == c[:, :-1]  # (M, L-1): frame p equals p+1
    idx = np.broadcast_to(np.arange(length), (m, length))
    is_start = np.ones((m, length), dtype=bool)
    is_start[:, 1:] = ~equal_next
    is_end = np.ones((m, length), dtype=bool)
    is_end[:, :-1] = ~equal_next
    # the end of the run each start belongs to: next run end at or after p
    ends = np.where(is_end, idx, length)
    run_end = np.minimum.accumulate(ends[:, ::-1], axis=1)[:, ::-1]
    rows, starts = np.nonzero(is_start)
    stops = run_end[rows, starts]
    inner = (starts >= 1) & (stops <= length - 2)
    rows, starts, stops = rows[inner], starts[inner], stops[inner]
    rising = c[rows, starts - 1] < c[rows, starts]
    falling = c[rows, stops + 1] < c[rows, stops]
    keep = rising & falling
    out[rows[keep], (starts[keep] + stops[keep]) // 2] = True
    return out


def _check_curves(curves: np.ndarray, n_keyframes: int) -> np.ndarray:
    c = np.asarray(curves, dtype=np.float64)
    if c.ndim != 2:
        raise InputError(f"curves must be (measures, frames), got shape {c.shape}")
    if not np.isfinite(c).all():
        raise InputError("keyframe curve holds NaN or Inf")
    if n_keyframes < 2:
        raise InputError(f"need at least 2 keyframes (first and last frame), got {n_keyframes}")
    if c.shape[1] < n_keyframes:
        raise InputError(f"a measure of {c.shape[1]} frames cannot hold {n_keyframes} keyframes")
    return c


def _fill_choice_adjacent(
    selected: np.ndarray, c: np.ndarray, length: int
) -> tuple[np.ndarray, np.ndarray]:
    """For each row of sorted ``selected`` (padded with ``length``), the frame the
    ``adjacent_max_sum`` rule inserts, and whether the row has any eligible pair."""
    a, b = selected[:, :-1], selected[:, 1:]
    eligible = (b < length) & (b - a >= 2)
    ca = np.take_along_axis(c, np.minimum(a, length - 1), axis=1)
    cb = np.take_along_axis(c, np.minimum(b, length - 1), axis=1)
    score = np.where(eligible, ca + cb, -np.inf)
    best = score.max(axis=1, keepdims=True)
    tied = eligible & (score == best)
    gap = np.where(tied, b - a, -1)
    tied &= gap == gap.max(axis=1, keepdims=True)
    pick = np.argmax(tied, axis=1)  # first True: the smallest a (rows are sorted)
    rows = np.arange(selected.shape[0])
    return (a[rows, pick] + b[rows, pick]) // 2, eligible.any(axis=1)


def _fill_choice_top2(
    selected: np.ndarray, c: np.ndarray, length: int
) -> tuple[np.ndarray, np.ndarray]:
    """The ``top2_midpoint`` insertion per row; second value: the midpoint is new (else the
    caller falls back to ``adjacent_max_sum``)."""
    valid = selected < length
    values = np.take_along_axis(c, np.minimum(selected, length - 1), axis=1)
    # rank by value descending, ties to the smaller index; invalid slots last
    order = np.lexsort((selected, np.where(valid, -values, np.inf)), axis=1)
    first = np.take_along_axis(selected, order[:, :1], axis=1)[:, 0]
    second = np.take_along_axis(selected, order[:, 1:2], axis=1)[:, 0]
    mid = (np.minimum(first, second) + np.maximum(first, second)) // 2
    is_new = ~(selected == mid[:, None]).any(axis=1)
    return mid, is_new


def peak_keyframes_batch(
    curves: np.ndarray,
    n_keyframes: int,
    guard: int = 6,
    fill: str = "adjacent_max_sum",
    candidates: np.ndarray | None = None,
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Peak-picked keyframes of M measures of equal length L.

    Args:
        curves: (M, L) curve values of each measure (finite).
        n_keyframes: N, counting the first and last frame.
        guard: edge guard G in frames: candidates p < G or p > L−1−G are dropped.
        fill: ``adjacent_max_sum`` or ``top2_midpoint`` (module docstring).
        candidates: optional (M, L) bool mask replacing the local-maximum detector (e.g. the
            stored ``audio/onset_peaks``); frames 0 and L−1 are never candidates.

    Returns:
        indices (M, N) int64 strictly increasing local frames, sources (M, N) int8 codes into
        :data:`KEYFRAME_SOURCES`, scores (M, N) float64: the curve value at peaks and fills,
        NaN at the two edges.
    """
    c = _check_curves(curves, n_keyframes)
    if fill not in FILL_RULES:
        raise InputError(f"unknown fill rule {fill!r}; known: {', '.join(FILL_RULES)}")
    if guard < 0:
        raise InputError(f"edge guard must be ≥ 0 frames, got {guard}")
    m, length = c.shape
    if candidates is None:
        cand = local_maxima(c)
    else:
        cand = np.asarray(candidates, dtype=bool).copy()
        if cand.shape != c.shape:
            raise InputError(f"peak candidates have shape {cand.shape}, curves {c.shape}")
        cand[:, 0] = cand[:, -1] = False
    frames = np.arange(length)
    cand &= (frames >= guard) & (frames <= length - 1 - guard)

    n_inner = n_keyframes - 2
    # Ranking: value descending, ties to the smaller index (stable sort over frame order).
    order = np.argsort(np.where(cand, -c, np.inf), axis=1, kind="stable")[:, :n_inner]
    taken = np.take_along_axis(cand, order, axis=1)
    selected = np.full((m, n_keyframes), length, dtype=np.int64)  # `length` pads empty slots
    sources = np.full((m, n_keyframes), -1, dtype=np.int8)
    selected[:, 0], selected[:, 1] = 0, length - 1
    sources[:, :2] = EDGE
    selected[:, 2:] = np.where(taken, order, length)
    sources[:, 2:] = np.where(taken, PEAK, -1)
    count = 2 + taken.sum(axis=1)

    def sort_rows() -> None:
        nonlocal selected, sources
        perm = np.argsort(selected, axis=1, kind="stable")
        selected = np.take_along_axis(selected, perm, axis=1)
        sources = np.take_along_axis(sources, perm, axis=1)

    sort_rows()
    while (count < n_keyframes).any():
        rows = np.nonzero(count < n_keyframes)[0]
        sub, csub = selected[rows], c[rows]
        new, ok = _fill_choice_adjacent(sub, csub, length)
        if fill == "top2_midpoint":
            mid, is_new = _fill_choice_top2(sub, csub, length)
            new = np.where(is_new, mid, new)
            ok |= is_new
        if not ok.all():  # cannot happen with L ≥ N; guard against an endless loop anyway
            raise InputError(f"no room to fill keyframes in a measure of {length} frames")
        slot = count[rows]
        selected[rows, slot] = new
        sources[rows, slot] = FILL
        count[rows] += 1
        sort_rows()
    scores = np.take_along_axis(c, selected, axis=1)
    scores[sources == EDGE] = np.nan
    return selected, sources, scores
