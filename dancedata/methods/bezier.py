"""Cubic Bézier in-betweening per channel (docs/EXPERIMENTS.md §3.2), vectorised over segments.

Each channel c of the 75-d Euler layout (3 translation in m + 72 Euler angles in rad) is a
scalar curve; on a segment (a, b) with ``u = (t − a)/(b − a)``,

    C_c(u) = (1−u)³ P0 + 3(1−u)²u P1 + 3(1−u)u² P2 + u³ P3,   P0 = x_a[c], P3 = x_b[c].

Control points P1, P2:

- ``oracle`` (used with DP keyframes): least squares over the segment's own frames,
  ``argmin Σ_t (C_c(u_t) − x_t[c])²``. The problem is linear in (P1, P2), so Levenberg–Marquardt
  (the seed: scipy, LM) converges to the closed-form solution; :func:`bezier_fit` solves the 2×2
  normal equations of every segment and channel at once (``solver="closed_form"``, default) or
  calls ``scipy.optimize.least_squares(method="lm")`` per segment (``solver="lm"``, for parity
  checks; slow). They agree to ~1e-10.
- ``train_mean`` (used with even keyframes): :class:`BezierTrainMean` averages the oracle
  control points of the train split per (channel, segment slot) or per channel, as absolute
  values (default, the literal reading) or chord-relative ``α = (P − P0)/(P3 − P0)``.

Segments with ``b − a < 3`` have fewer than two interior frames: their control points are the
linear ones ``P1 = P0 + (P3−P0)/3``, ``P2 = P0 + 2(P3−P0)/3`` and the cubic is the chord.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

from dancedata.errors import InputError
from dancedata.methods.inbetween import EulerOrder, Reconstruction, SegmentMap, _rows

BEZIER_SOLVERS: tuple[str, ...] = ("closed_form", "lm")
BEZIER_GROUPS: tuple[str, ...] = ("channel_slot", "channel")
BEZIER_PARAMS: tuple[str, ...] = ("absolute", "chord_relative")
BEZIER_TRANS: tuple[str, ...] = ("bezier", "linear")
MIN_BEZIER_GAP = 3  # b − a below this: linear control points
CHORD_GUARD = 1e-6  # |P3 − P0| below this: no chord-relative α from this segment


def bernstein3(u: np.ndarray) -> np.ndarray:
    """(..., 4) cubic Bernstein basis B_0 … B_3 at u."""
    u = np.asarray(u, dtype=np.float64)[..., None]
    v = 1.0 - u
    return np.concatenate([v**3, 3.0 * v**2 * u, 3.0 * v * u**2, u**3], axis=-1)


def linear_control_points(p0: np.ndarray, p3: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The control points that make the cubic the straight chord from p0 to p3."""
    return p0 + (p3 - p0) / 3.0, p0 + 2.0 * (p3 - p0) / 3.0


def _channels(x: np.ndarray, segments: SegmentMap) -> np.ndarray:
    """``x`` checked, not converted (callers gather rows, then convert: see ``_rows``)."""
    values = np.asarray(x)
    if values.ndim != 2:
        raise InputError(f"Bézier input must be (frames, channels), got shape {values.shape}")
    if segments.frame.size and int(segments.frame.max()) >= values.shape[0]:
        raise InputError(f"Bézier input has {values.shape[0]} frames; the segments need more")
    return values


def _segment_starts(segments: SegmentMap) -> np.ndarray:
    """Index into the map's frames where each segment's run starts (segments are contiguous
    and every segment holds at least its left keyframe)."""
    return np.unique(segments.segment, return_index=True)[1]


def _fit_closed_form(values: np.ndarray, segments: SegmentMap) -> tuple[np.ndarray, np.ndarray]:
    basis = bernstein3(segments.u)  # (F', 4)
    xa, xb = _rows(values, segments.left), _rows(values, segments.right)
    target = _rows(values, segments.frame) - basis[:, :1] * xa - basis[:, 3:] * xb  # (F', C)
    starts = _segment_starts(segments)
    b1, b2 = basis[:, 1], basis[:, 2]
    a11 = np.add.reduceat(b1 * b1, starts)
    a12 = np.add.reduceat(b1 * b2, starts)
    a22 = np.add.reduceat(b2 * b2, starts)
    r1 = np.add.reduceat(b1[:, None] * target, starts, axis=0)  # (S, C)
    r2 = np.add.reduceat(b2[:, None] * target, starts, axis=0)
    det = (a11 * a22 - a12 * a12)[:, None]
    safe = np.where(det > 0, det, 1.0)
    p1 = (a22[:, None] * r1 - a12[:, None] * r2) / safe
    p2 = (a11[:, None] * r2 - a12[:, None] * r1) / safe
    return p1, p2


def _fit_lm(values: np.ndarray, segments: SegmentMap, tol: float) -> tuple[np.ndarray, np.ndarray]:
    """One scipy LM problem per segment, all channels jointly (2C unknowns)."""
    from scipy.optimize import least_squares

    a_all, b_all = segments.segment_ends()
    n_channels = values.shape[1]
    p1 = np.empty((a_all.size, n_channels))
    p2 = np.empty((a_all.size, n_channels))
    for s, (a, b) in enumerate(zip(a_all.tolist(), b_all.tolist(), strict=True)):
        xa, xb = _rows(values, a), _rows(values, b)
        lin1, lin2 = linear_control_points(xa, xb)
        if b - a < MIN_BEZIER_GAP:
            p1[s], p2[s] = lin1, lin2
            continue
        basis = bernstein3((np.arange(a, b + 1) - a) / (b - a))  # (n, 4)
        target = _rows(values, slice(a, b + 1)) - basis[:, :1] * xa - basis[:, 3:] * xb

        def residual(p: np.ndarray, basis=basis, target=target) -> np.ndarray:
            q1, q2 = p[:n_channels], p[n_channels:]
            return (basis[:, 1:2] * q1 + basis[:, 2:3] * q2 - target).reshape(-1)

        fit = least_squares(
            residual,
            np.concatenate([lin1, lin2]),
            method="lm",
            xtol=tol,
            ftol=tol,
            gtol=tol,
        )
        p1[s], p2[s] = fit.x[:n_channels], fit.x[n_channels:]
    return p1, p2


def bezier_fit(
    x: np.ndarray, segments: SegmentMap, solver: str = "closed_form", lm_tol: float = 1e-12
) -> tuple[np.ndarray, np.ndarray]:
    """Oracle control points of every segment and channel.

    Args:
        x: (F, C) channels of the motion the map indexes (the 75-d Euler layout).
        segments: the segments to fit.
        solver: ``closed_form`` (2×2 normal equations, vectorised) or ``lm``
            (``scipy.optimize.least_squares(method="lm")`` per segment, tolerances ``lm_tol``).

    Returns:
        P1, P2 as (S, C) float64, S = M·(N−1) in segment-id order; linear control points for
        segments with b − a < 3.
    """
    if solver not in BEZIER_SOLVERS:
        raise InputError(f"unknown Bézier solver {solver!r}; known: {', '.join(BEZIER_SOLVERS)}")
    values = _channels(x, segments)
    if solver == "lm":
        return _fit_lm(values, segments, lm_tol)
    p1, p2 = _fit_closed_form(values, segments)
    a, b = segments.segment_ends()
    short = (b - a) < MIN_BEZIER_GAP
    if short.any():
        lin1, lin2 = linear_control_points(_rows(values, a[short]), _rows(values, b[short]))
        p1[short], p2[short] = lin1, lin2
    return p1, p2


def bezier_eval(x: np.ndarray, segments: SegmentMap, p1: np.ndarray, p2: np.ndarray) -> np.ndarray:
    """(F', C) the cubic of every segment at its frames; keyframe rows are x's own rows."""
    values = _channels(x, segments)
    seg = segments.segment
    basis = bernstein3(segments.u)
    out = (
        basis[:, :1] * _rows(values, segments.left)
        + basis[:, 1:2] * p1[seg]
        + basis[:, 2:3] * p2[seg]
        + basis[:, 3:] * _rows(values, segments.right)
    )
    keep = segments.is_keyframe
    out[keep] = _rows(values, segments.frame[keep])
    return out


def linear_channels(x: np.ndarray, segments: SegmentMap) -> np.ndarray:
    """(F', C) per-channel linear interpolation between keyframes (the ``euler_linear``
    comparison baseline of §3.1: Euler angles interpolated as numbers, not rotations)."""
    values = _channels(x, segments)
    u = segments.u[:, None]
    out = (1.0 - u) * _rows(values, segments.left) + u * _rows(values, segments.right)
    keep = segments.is_keyframe
    out[keep] = _rows(values, segments.frame[keep])
    return out


@dataclass
class BezierTrainMean:
    """Control points averaged over the train split (docs/EXPERIMENTS.md §3.2, ``train_mean``).

    ``group``: ``channel_slot`` (one mean per channel and segment slot k = 0 … N−2; needs the
    same N at fit and predict) or ``channel``. ``param``: ``absolute`` (mean of P1, P2 in m/rad)
    or ``chord_relative`` (mean of α = (P − P0)/(P3 − P0), segments with |P3 − P0| < 1e-6
    left out of the mean; a group with none left uses the linear α = 1/3, 2/3).
    """

    group: str = "channel_slot"
    param: str = "absolute"
    mean1: np.ndarray | None = None  # (K, C): K = N − 1 slots, or 1 for "channel"
    mean2: np.ndarray | None = None
    n_keyframes: int | None = None
    n_segments: int = 0

    def __post_init__(self) -> None:
        if self.group not in BEZIER_GROUPS:
            raise InputError(f"unknown Bézier group {self.group!r}; known: {BEZIER_GROUPS}")
        if self.param not in BEZIER_PARAMS:
            raise InputError(f"unknown Bézier param {self.param!r}; known: {BEZIER_PARAMS}")

    def _slots(self, segments: SegmentMap) -> np.ndarray:
        """(S,) group index of every segment."""
        slots = np.tile(np.arange(segments.n_keyframes - 1), segments.n_measures)
        return slots if self.group == "channel_slot" else np.zeros_like(slots)

    def fit(self, x: np.ndarray, segments: SegmentMap, solver: str = "closed_form") -> Any:
        """Fit the means from the train measures' oracle control points; returns self."""
        values = _channels(x, segments)
        p1, p2 = bezier_fit(values, segments, solver)
        a, b = segments.segment_ends()
        p0, p3 = _rows(values, a), _rows(values, b)
        if self.param == "chord_relative":
            chord = p3 - p0
            valid = np.abs(chord) >= CHORD_GUARD
            safe = np.where(valid, chord, 1.0)
            v1, v2 = (p1 - p0) / safe, (p2 - p0) / safe
            default1, default2 = 1.0 / 3.0, 2.0 / 3.0
        else:
            valid = np.ones_like(p1, dtype=bool)
            v1, v2 = p1, p2
            default1 = default2 = 0.0
        groups = self._slots(segments)
        n_groups = int(groups.max(initial=-1)) + 1
        weight = np.zeros((n_groups, values.shape[1]))
        sum1 = np.zeros_like(weight)
        sum2 = np.zeros_like(weight)
        np.add.at(weight, groups, valid.astype(np.float64))
        np.add.at(sum1, groups, np.where(valid, v1, 0.0))
        np.add.at(sum2, groups, np.where(valid, v2, 0.0))
        has = weight > 0
        self.mean1 = np.where(has, sum1 / np.where(has, weight, 1.0), default1)
        self.mean2 = np.where(has, sum2 / np.where(has, weight, 1.0), default2)
        self.n_keyframes = segments.n_keyframes
        self.n_segments = segments.n_segments
        return self

    def control_points(self, x: np.ndarray, segments: SegmentMap) -> tuple[np.ndarray, np.ndarray]:
        """P1, P2 (S, C) for the evaluation segments from the fitted means."""
        if self.mean1 is None or self.mean2 is None:
            raise InputError("BezierTrainMean.control_points before fit")
        if self.group == "channel_slot" and segments.n_keyframes != self.n_keyframes:
            raise InputError(
                f"train means were fitted with N = {self.n_keyframes} keyframes per measure, "
                f"the evaluation segments have N = {segments.n_keyframes}"
            )
        values = _channels(x, segments)
        groups = self._slots(segments)
        m1, m2 = self.mean1[groups], self.mean2[groups]
        if self.param == "absolute":
            return m1.copy(), m2.copy()
        a, b = segments.segment_ends()
        p0, p3 = _rows(values, a), _rows(values, b)
        return p0 + m1 * (p3 - p0), p0 + m2 * (p3 - p0)

    def config(self) -> dict[str, Any]:
        return {"bezier_group": self.group, "bezier_param": self.param}


def bezier_reconstruction(
    x75: np.ndarray,
    segments: SegmentMap,
    p1: np.ndarray,
    p2: np.ndarray,
    euler_order: EulerOrder = "XYZ",
    trans_mode: str = "bezier",
) -> Reconstruction:
    """A :class:`Reconstruction` from 75-d (3 + 3J) Euler rows and control points.

    ``trans_mode`` ``linear`` replaces the translation channels' control points by the linear
    ones (option ``bezier_trans = "linear"``); ``bezier`` (default) keeps them.
    """
    if trans_mode not in BEZIER_TRANS:
        raise InputError(f"unknown bezier_trans {trans_mode!r}; known: {BEZIER_TRANS}")
    values = _channels(x75, segments)
    if (values.shape[1] - 3) % 3:
        raise InputError(f"expected 3 + 3J channels, got {values.shape[1]}")
    if trans_mode == "linear":
        a, b = segments.segment_ends()
        p1, p2 = p1.copy(), p2.copy()
        p1[:, :3], p2[:, :3] = linear_control_points(
            _rows(values, a)[:, :3], _rows(values, b)[:, :3]
        )
    curve = bezier_eval(values, segments, p1, p2)
    n = curve.shape[0]
    return Reconstruction(
        segments,
        trans=curve[:, :3],
        euler_order=euler_order,
        euler=curve[:, 3:].reshape(n, -1, 3),
    )
