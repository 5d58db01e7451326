"""Dynamic-programming keyframes, Roberts 2018 "Salient Poses" (docs/METRICS.md, "DP keyframe
distance"), batched.

A measure is a curve ``x_i ∈ R^D``, i = 0 … L−1 (``thesis_euler_75`` rows: metres and radians,
unweighted). The error of keeping only frames a and b of a segment is the largest distance of
an in-between frame from the straight line between them:

- ``vertical`` (default): ``e(a,b) = max_i ‖x_i − (x_a + s_i (x_b − x_a))‖`` with
  ``s_i = (i − a)/(b − a)``, the distance at the same frame between a pose and its linear
  interpolation. This is the distance the thesis whose tables the experiments reproduce
  (Lin 2022, §2.4.1) describes: "the maximum distance between the value of a point on the
  segment and its value reconstructed by a curve linearly interpolated between two ending
  points". It is the default because those tables are the target, and because it is in the
  data's own units (metres and radians) at any frame rate, and it is exactly the error that
  linear in-betweening of the chosen keyframes leaves at the worst frame.
- ``perpendicular``, Roberts' distance (his reference code ``KeyframeSelection``,
  ``max_point_to_line_distance``): the distance of ``y_i = (i, x_i)`` from the line through
  ``y_a`` and ``y_b`` in (time in frames, values) space. It mixes frames with metres and
  radians (one frame weighs as much as one metre), so it changes with the frame rate; selected
  by name (``dp_distance = "perpendicular"``), it reproduces Roberts' selections, ties
  included.

``C_k(t)``, the cost of the best k keyframes on [0, t] with 0 and t kept, is
``C_2(t) = e(0, t)`` and ``C_k(t) = min_{j} combine(C_{k−1}(j), e(j, t))``; the answer is
``C_N(L−1)``, the keyframes come from back-tracking the argmin j, and ties go to the smallest j
(Roberts' strict ``<`` while j increases). ``combine`` is ``max`` (minimax, Roberts' code and the
default) or ``sum`` (the seed's prose; it degenerates, see the spec; kept for the record).

Speed: the O(L³) error table is computed from each measure's Gram matrix, so no D-dimensional
work happens inside the cubic part: by a compiled loop (numba, a librosa dependency) or, as a
fallback and cross-check, for a whole batch of equal-length measures at once, one gap ``b − a``
at a time over strided views (no gathers). The DP is O(N·L²) per measure, also
batched. The table entries carry the rounding of a Gram-matrix expansion (in tests within 1e-9
of the definition, up to ~1e-7 absolute for errors near 0); :func:`segment_errors` computes
chosen segments' errors directly from the definition.
"""

from __future__ import annotations

from typing import Any

import numpy as np
from numpy.lib.stride_tricks import as_strided

from dancedata.errors import InputError

DP_DISTANCES: tuple[str, ...] = ("vertical", "perpendicular")
DP_COMBINES: tuple[str, ...] = ("max", "sum")


def _check_distance(distance: str) -> None:
    if distance not in DP_DISTANCES:
        raise InputError(f"unknown DP distance {distance!r}; known: {', '.join(DP_DISTANCES)}")


def _gram(values: np.ndarray) -> np.ndarray:
    """(M, L, L) Gram matrices of the measures, centred first (distances are translation-free;
    centring keeps the expansion's cancellation error near 1e-16 of the data's spread)."""
    centred = values - values.mean(axis=1, keepdims=True)
    return np.ascontiguousarray(centred @ centred.transpose(0, 2, 1))


def _error_table_numpy(gram: np.ndarray, perpendicular: bool) -> np.ndarray:
    """The error table from Gram matrices, one gap b − a at a time over strided views."""
    m, length, _ = gram.shape
    table = np.full((m, length, length), np.inf)
    a_all = np.arange(length)
    table[:, a_all[:-1], a_all[:-1] + 1] = 0.0  # e(a, a+1): no frame in between
    s_m, s_r, s_c = gram.strides
    diag = np.diagonal(gram, axis1=1, axis2=2)  # (M, L)
    for gap in range(2, length):
        n_a, n_j = length - gap, gap - 1
        shape, step = (m, n_j, n_a), (s_m, s_r, s_r + s_c)
        # G[a+j, a+j], G[a+j, a], G[a+j, a+gap] for j = 1 … gap−1 (rows), a = 0 … L−gap−1
        g_ii = as_strided(gram[:, 1:, 1:], shape, (s_m, s_r + s_c, s_r + s_c), writeable=False)
        g_ia = as_strided(gram[:, 1:, :], shape, step, writeable=False)
        g_ib = as_strided(gram[:, 1:, gap:], shape, step, writeable=False)
        g_ab = np.diagonal(gram, offset=gap, axis1=1, axis2=2)
        ends = np.stack([diag[:, :n_a], g_ab, diag[:, gap : gap + n_a]], axis=1)  # (M, 3, n_a)
        s = np.arange(1, gap, dtype=np.float64)[:, None] / gap  # (n_j, 1)
        # ‖x_i − (1−s) x_a − s x_b‖² = G_ii − 2(1−s) G_ia − 2s G_ib + ‖(1−s) x_a + s x_b‖²
        coef = np.concatenate([(1.0 - s) ** 2, 2.0 * s * (1.0 - s), s**2], axis=1)
        dist2 = coef @ ends  # (M, n_j, n_a)
        dist2 += g_ii
        term = np.multiply(g_ia, 2.0 * s - 2.0)
        dist2 += term
        np.multiply(g_ib, -2.0 * s, out=term)
        dist2 += term
        if perpendicular:
            # The vertical residual r has time component 0 (the lift's time is linear), so
            # the perpendicular residual is r minus its projection on v = y_b − y_a.
            vv_x = ends[:, 0] - 2.0 * ends[:, 1] + ends[:, 2]  # ‖x_b − x_a‖², (M, n_a)
            r_dot_v = g_ib - g_ia - (g_ab - ends[:, 0])[:, None, :] - s * vv_x[:, None, :]
            dist2 -= r_dot_v**2 / (vv_x[:, None, :] + float(gap) ** 2)
        worst = np.sqrt(np.maximum(dist2.max(axis=1), 0.0))  # (M, n_a)
        table[:, a_all[:n_a], a_all[:n_a] + gap] = worst
    return table


_NUMBA_KERNELS: dict[bool, Any] = {}


def _numba_kernel(perpendicular: bool) -> Any:  # pragma: no cover - runs whenever numba imports
    """The same expansion as :func:`_error_table_numpy` as a compiled triple loop (5–20×
    faster: no temporaries), one specialisation per distance so the inner loop has no branch.
    Compiled once per process (about 0.5 s each), never cached on disk."""
    if perpendicular not in _NUMBA_KERNELS:
        import numba

        perp = bool(perpendicular)

        @numba.njit(cache=False)
        def kernel(gram, table):
            m, length, _ = gram.shape
            diag = np.empty(length)
            for mm in range(m):
                g = gram[mm]
                for i in range(length):
                    diag[i] = g[i, i]
                for a in range(length - 1):
                    table[mm, a, a + 1] = 0.0
                    g_aa = diag[a]
                    row_a = g[a]  # G is symmetric: G[i, a] = G[a, i], contiguous in i
                    for b in range(a + 2, length):
                        row_b = g[b]
                        g_ab, g_bb = row_a[b], diag[b]
                        gap = b - a
                        inv = 1.0 / gap
                        vv_x = g_bb - 2.0 * g_ab + g_aa
                        vv = vv_x + gap * gap
                        worst = 0.0
                        for i in range(a + 1, b):
                            s = (i - a) * inv
                            d2 = (
                                diag[i]
                                - 2.0 * (1.0 - s) * row_a[i]
                                - 2.0 * s * row_b[i]
                                + (1.0 - s) * (1.0 - s) * g_aa
                                + 2.0 * s * (1.0 - s) * g_ab
                                + s * s * g_bb
                            )
                            if perp:
                                r_dot_v = row_b[i] - row_a[i] - g_ab + g_aa - s * vv_x
                                d2 -= r_dot_v * r_dot_v / vv
                            worst = max(worst, d2)
                        table[mm, a, b] = np.sqrt(worst)

        _NUMBA_KERNELS[perpendicular] = kernel
    return _NUMBA_KERNELS[perpendicular]


def _numba_available() -> bool:
    try:
        import numba  # noqa: F401
    except ImportError:  # pragma: no cover - librosa depends on numba
        return False
    return True


ENGINES: tuple[str, ...] = ("auto", "numba", "numpy")


def segment_error_table(
    x: np.ndarray, distance: str = "vertical", engine: str = "auto"
) -> np.ndarray:
    """Segment errors e(a, b) of M equal-length measures.

    Args:
        x: (M, L, D) or (L, D) curves.
        distance: ``vertical`` or ``perpendicular``.
        engine: ``numba`` (compiled loop), ``numpy`` (strided vector form) or ``auto`` (numba
            when importable). Both evaluate the same expansion and agree to rounding.

    Returns:
        (M, L, L) float64 (or (L, L) for 2-d input): ``E[m, a, b] = e(a, b)`` for a < b, in the
        units of x (for ``perpendicular``, of the (frames, x) lift); ``+inf`` where a ≥ b.
    """
    _check_distance(distance)
    if engine not in ENGINES:
        raise InputError(f"unknown engine {engine!r}; known: {', '.join(ENGINES)}")
    values = np.asarray(x, dtype=np.float64)
    single = values.ndim == 2
    if single:
        values = values[None]
    if values.ndim != 3:
        raise InputError(f"DP input must be (measures, frames, dims), got shape {values.shape}")
    gram = _gram(values)
    perpendicular = distance == "perpendicular"
    if engine == "numpy" or (engine == "auto" and not _numba_available()):
        table = _error_table_numpy(gram, perpendicular)
    else:
        m, length, _ = gram.shape
        table = np.full((m, length, length), np.inf)
        _numba_kernel(perpendicular)(gram, table)
    return table[0] if single else table


def segment_errors(x: np.ndarray, keyframes: np.ndarray, distance: str = "vertical") -> np.ndarray:
    """Direct (not Gram) errors of the segments between consecutive keyframes.

    Args:
        x: (M, L, D) curves; keyframes: (M, N) sorted local indices.

    Returns:
        (M, N−1) float64: ``e(k_n, k_{n+1})`` per segment.
    """
    _check_distance(distance)
    values = np.asarray(x, dtype=np.float64)
    kf = np.asarray(keyframes, dtype=np.int64)
    m, length, _ = values.shape
    frames = np.arange(length)
    # the segment each frame lies in (its right end belongs to the segment before)
    seg = np.clip(
        np.sum(frames[None, :, None] > kf[:, None, 1:-1], axis=2), 0, kf.shape[1] - 2
    )  # (M, L)
    a = np.take_along_axis(kf, seg, axis=1)
    b = np.take_along_axis(kf, seg + 1, axis=1)
    s = ((frames[None] - a) / (b - a))[..., None]
    xa = np.take_along_axis(values, a[..., None], axis=1)
    xb = np.take_along_axis(values, b[..., None], axis=1)
    resid = values - xa - s * (xb - xa)
    dist2 = np.sum(resid**2, axis=-1)
    if distance == "perpendicular":
        v = xb - xa
        r_dot_v = np.sum(resid * v, axis=-1)
        dist2 = dist2 - r_dot_v**2 / (np.sum(v**2, axis=-1) + (b - a) ** 2)
    dist = np.sqrt(np.maximum(dist2, 0.0))
    # segment ids m·(N−1) + seg never decrease along the flattened frames, and every segment
    # holds at least one frame (its right keyframe): one reduceat gives every segment's max
    n_seg = kf.shape[1] - 1
    flat = (np.arange(m)[:, None] * n_seg + seg).reshape(-1)
    starts = np.flatnonzero(np.r_[True, flat[1:] != flat[:-1]])
    return np.maximum.reduceat(dist.reshape(-1), starts).reshape(m, n_seg)


_DP_KERNELS: dict[bool, Any] = {}


def _dp_kernel(use_sum: bool) -> Any:  # pragma: no cover - runs whenever numba imports
    """The recurrence of :func:`dp_tables` as a compiled loop, one specialisation per combine:
    same candidates, same strict ``<`` over increasing j (the smallest j wins ties)."""
    if use_sum not in _DP_KERNELS:
        import numba

        add = bool(use_sum)

        @numba.njit(cache=False)
        def kernel(errors, max_keyframes, costs, back):
            m, length, _ = errors.shape
            for mm in range(m):
                e = errors[mm]
                for k in range(3, max_keyframes + 1):
                    prev = costs[k - 1, mm]
                    for t in range(length):
                        best = np.inf
                        arg = 0
                        for j in range(t):
                            value = prev[j] + e[j, t] if add else max(prev[j], e[j, t])
                            if value < best:
                                best = value
                                arg = j
                        costs[k, mm, t] = best
                        back[k, mm, t] = arg

        _DP_KERNELS[use_sum] = kernel
    return _DP_KERNELS[use_sum]


def dp_tables(
    errors: np.ndarray, max_keyframes: int, combine: str = "max", engine: str = "auto"
) -> tuple[np.ndarray, np.ndarray]:
    """The DP over a batch: costs ``C[k, m, t]`` and back-pointers ``back[k, m, t]`` for
    k = 2 … max_keyframes (rows 0 and 1 unused).

    Args:
        errors: (M, L, L) segment errors from :func:`segment_error_table`.
        max_keyframes: the largest N wanted; every smaller N is read off the same tables.
        combine: ``max`` (minimax) or ``sum``.
        engine: ``numba``, ``numpy`` or ``auto`` (as :func:`segment_error_table`).
    """
    if combine not in DP_COMBINES:
        raise InputError(f"unknown DP combine {combine!r}; known: {', '.join(DP_COMBINES)}")
    if engine not in ENGINES:
        raise InputError(f"unknown engine {engine!r}; known: {', '.join(ENGINES)}")
    m, length, _ = errors.shape
    if max_keyframes < 2 or max_keyframes > length:
        raise InputError(
            f"a measure of {length} frames cannot hold {max_keyframes} keyframes (need 2 … L)"
        )
    costs = np.full((max_keyframes + 1, m, length), np.inf)
    back = np.zeros((max_keyframes + 1, m, length), dtype=np.int64)
    costs[2] = errors[:, 0, :]  # C_2(t) = e(0, t); e(0, 0) = inf
    if engine == "numba" or (engine == "auto" and _numba_available()):
        _dp_kernel(combine == "sum")(np.ascontiguousarray(errors), max_keyframes, costs, back)
        return costs, back
    join = np.maximum if combine == "max" else np.add
    for k in range(3, max_keyframes + 1):
        # candidate[m, j, t] = combine(C_{k−1}(j), e(j, t)); inf where j ≥ t or j < k−2
        candidate = join(costs[k - 1][:, :, None], errors)
        back[k] = np.argmin(candidate, axis=1)  # first minimum: the smallest j wins ties
        costs[k] = np.take_along_axis(candidate, back[k][:, None, :], axis=1)[:, 0, :]
    return costs, back


def dp_backtrack(
    costs: np.ndarray, back: np.ndarray, n_keyframes: int
) -> tuple[np.ndarray, np.ndarray]:
    """Keyframes (M, N) int64 and their cost ``C_N(L−1)`` (M,) from :func:`dp_tables`."""
    _, m, length = costs.shape
    kf = np.zeros((m, n_keyframes), dtype=np.int64)
    kf[:, -1] = length - 1
    rows = np.arange(m)
    t = np.full(m, length - 1)
    for k in range(n_keyframes, 2, -1):
        t = back[k][rows, t]
        kf[:, k - 2] = t
    return kf, costs[n_keyframes][:, length - 1].copy()


def dp_keyframes_batch(
    x: np.ndarray,
    n_keyframes: list[int] | tuple[int, ...],
    distance: str = "vertical",
    combine: str = "max",
    engine: str = "auto",
) -> dict[int, tuple[np.ndarray, np.ndarray, np.ndarray]]:
    """DP keyframes of M equal-length measures for every N in ``n_keyframes`` at once (one
    error table and one DP serve them all).

    Returns:
        N → (indices (M, N) int64, DP cost C_N(L−1) (M,), segment scores (M, N): NaN for the
        first keyframe, else e(·) of the segment ending there, from the error table).
    """
    values = np.asarray(x, dtype=np.float64)
    if values.ndim != 3:
        raise InputError(f"DP input must be (measures, frames, dims), got shape {values.shape}")
    if not np.isfinite(values).all():
        raise InputError("DP input holds NaN or Inf")
    errors = segment_error_table(values, distance, engine)
    costs, back = dp_tables(errors, max(n_keyframes), combine, engine)
    out = {}
    for n in n_keyframes:
        kf, cost = dp_backtrack(costs, back, n)
        scores = np.full(kf.shape, np.nan)
        rows = np.arange(kf.shape[0])[:, None]
        scores[:, 1:] = errors[rows, kf[:, :-1], kf[:, 1:]]  # e(k_{n−1}, k_n) from the table
        out[n] = (kf, cost, scores)
    return out
