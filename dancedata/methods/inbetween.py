"""In-betweening between keyframes (docs/EXPERIMENTS.md §3), vectorised over measures.

Every non-learned in-betweener works on segments: consecutive keyframes (a, b) of a measure,
frames t = a … b, parameter ``u = (t − a)/(b − a)``. A :class:`SegmentMap` lists every frame of
the evaluated measures with its segment, so one numpy expression reconstructs all measures of a
store at once, whatever their lengths: no loop over measures.

- :func:`linear_slerp` — §3.1: root translation linear in u, each joint's rotation by quaternion
  SLERP along the shorter arc (``dancedata.compute.resample.slerp``).
- :mod:`dancedata.methods.bezier` — §3.2: cubic Bézier per 75-d Euler channel.

Both return a :class:`Reconstruction`, which gives the layouts of the spec: ``euler75`` (trans m +
Euler rad in the store's order, = ``thesis_euler_75``), ``rotmat225`` (6 zeros + trans + 24×9
row-major, = ``fact_motion_225``) and axis-angle + trans for forward kinematics. Keyframe rows
are the ground truth's own rows, exactly.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import cached_property

import numpy as np

from dancedata.compute.motion_representations import euler_per_joint
from dancedata.compute.resample import slerp
from dancedata.compute.rotations import quat_to_axis_angle, quat_to_rotmat, rotmat_to_axis_angle
from dancedata.errors import InputError

EulerOrder = str | list[str]
SHORTEST_ARC = "q_b → −q_b when <q_a, q_b> < 0; nlerp when sin Ω < 1e-9"


@dataclass(frozen=True)
class SegmentMap:
    """Every frame of the evaluated measures, in measure order, with its keyframe segment.

    Attributes:
        frame: (F',) row of each frame in the motion arrays the map indexes (global frame).
        measure: (F',) index of its measure (row of ``starts``/``keyframes``).
        slot: (F',) segment number k = 0 … N−2 within the measure.
        left, right: (F',) global frames of the segment's keyframes a < b.
        u: (F',) float64 ``(t − a)/(b − a)`` in [0, 1].
        is_keyframe: (F',) bool.
        n_keyframes: N (keyframes per measure).
        n_measures: M.
    """

    frame: np.ndarray
    measure: np.ndarray
    slot: np.ndarray
    left: np.ndarray
    right: np.ndarray
    u: np.ndarray
    is_keyframe: np.ndarray
    n_keyframes: int
    n_measures: int

    @property
    def segment(self) -> np.ndarray:
        """(F',) segment id ``measure·(N−1) + slot`` (0 … M·(N−1)−1, non-decreasing)."""
        return self.measure * (self.n_keyframes - 1) + self.slot

    @property
    def n_segments(self) -> int:
        return self.n_measures * (self.n_keyframes - 1)

    def segment_ends(self) -> tuple[np.ndarray, np.ndarray]:
        """(S,) global frames a and b of every segment, in segment-id order."""
        first = np.unique(self.segment, return_index=True)[1]
        return self.left[first], self.right[first]


def segment_map(starts: np.ndarray, lengths: np.ndarray, keyframes: np.ndarray) -> SegmentMap:
    """The :class:`SegmentMap` of M measures.

    Args:
        starts: (M,) global frame of each measure's local frame 0.
        lengths: (M,) frames L per measure.
        keyframes: (M, N) local keyframe indices, strictly increasing, first 0 and last L−1.
    """
    starts = np.asarray(starts, dtype=np.int64)
    lengths = np.asarray(lengths, dtype=np.int64)
    kf = np.asarray(keyframes, dtype=np.int64)
    if kf.ndim != 2 or kf.shape[0] != starts.shape[0] or lengths.shape != starts.shape:
        raise InputError(
            f"keyframes {kf.shape}, starts {starts.shape} and lengths {lengths.shape} disagree"
        )
    m, n = kf.shape
    if n < 2:
        raise InputError("a measure needs at least 2 keyframes (first and last frame)")
    if m and (
        (kf[:, 0] != 0).any()
        or (kf[:, -1] != lengths - 1).any()
        or (np.diff(kf, axis=1) <= 0).any()
    ):
        raise InputError("keyframes must be strictly increasing from frame 0 to frame L−1")
    measure = np.repeat(np.arange(m), lengths)
    offsets = np.cumsum(lengths) - lengths
    local = np.arange(int(lengths.sum())) - np.repeat(offsets, lengths)
    # One searchsorted over all measures: place measure m at m·(Lmax+1) on a virtual axis.
    stride = int(lengths.max(initial=0)) + 1
    virtual_kf = (np.arange(m)[:, None] * stride + kf).reshape(-1)
    flat = np.searchsorted(virtual_kf, measure * stride + local, side="right") - 1
    slot = np.minimum(flat - measure * n, n - 2)  # the last frame closes the last segment
    a = kf[measure, slot]
    b = kf[measure, slot + 1]
    frame = starts[measure] + local
    return SegmentMap(
        frame=frame,
        measure=measure,
        slot=slot,
        left=starts[measure] + a,
        right=starts[measure] + b,
        u=(local - a) / (b - a),
        is_keyframe=(local == a) | (local == b),
        n_keyframes=n,
        n_measures=m,
    )


def euler_to_rotmat_per_joint(euler: np.ndarray, order: EulerOrder) -> np.ndarray:
    """(F, J, 3) Euler angles (rad) → (F, J, 3, 3); ``order`` one scipy order or one per joint."""
    from dancedata.compute.rotations import euler_to_rotmat

    if isinstance(order, str):
        return euler_to_rotmat(euler, order)
    if len(order) != euler.shape[1]:
        raise InputError(f"{len(order)} Euler orders for {euler.shape[1]} joints")
    out = np.empty(euler.shape[:2] + (3, 3))
    for one in set(order):
        joints = [j for j, o in enumerate(order) if o == one]
        out[:, joints] = euler_to_rotmat(euler[:, joints], one)
    return out


@dataclass
class Reconstruction:
    """Reconstructed frames of a :class:`SegmentMap` and their output layouts.

    Exactly one of ``quat`` (F', J, 4) wxyz and ``euler`` (F', J, 3) rad is the method's own
    output; the other layouts are converted from it (scipy, the store's ``euler_order``).
    ``truth_euler`` (F', J, 3), when given, supplies the keyframe rows of :meth:`euler75` so
    that they equal the stored ground truth bit for bit.
    """

    segments: SegmentMap
    trans: np.ndarray
    euler_order: EulerOrder
    quat: np.ndarray | None = None
    euler: np.ndarray | None = None
    truth_euler: np.ndarray | None = None

    @cached_property
    def rotmat(self) -> np.ndarray:
        """(F', J, 3, 3)."""
        if self.quat is not None:
            return quat_to_rotmat(self.quat)
        return euler_to_rotmat_per_joint(self.euler, self.euler_order)

    @cached_property
    def euler_angles(self) -> np.ndarray:
        """(F', J, 3) Euler angles in radians (principal branch when converted)."""
        if self.euler is not None:
            return self.euler
        out = euler_per_joint(self.rotmat, self.euler_order)
        if self.truth_euler is not None:
            keep = self.segments.is_keyframe
            out[keep] = self.truth_euler[keep]
        return out

    def euler75(self) -> np.ndarray:
        """(F', 3 + 3J) float64: trans (m) + Euler (rad), the ``thesis_euler_75`` layout."""
        f = self.trans.shape[0]
        return np.concatenate([self.trans, self.euler_angles.reshape(f, -1)], axis=1)

    def rotmat225(self) -> np.ndarray:
        """(F', 6 + 3 + 9J) float64: 6 zeros + trans + rotation matrices row-major, the
        ``fact_motion_225`` layout."""
        f = self.trans.shape[0]
        return np.concatenate([np.zeros((f, 6)), self.trans, self.rotmat.reshape(f, -1)], axis=1)

    def axis_angle(self) -> np.ndarray:
        """(F', J, 3) rotation vectors (rad), for forward kinematics (with :attr:`trans`)."""
        if self.quat is not None:
            return quat_to_axis_angle(self.quat)
        return rotmat_to_axis_angle(self.rotmat)


def _rows(values: np.ndarray, index: np.ndarray) -> np.ndarray:
    """``values[index]`` as float64 (the rows only, never the whole array)."""
    return np.asarray(values[index], dtype=np.float64)


def _check_frames(name: str, values: np.ndarray, segments: SegmentMap) -> None:
    if segments.frame.size and int(segments.frame.max()) >= values.shape[0]:
        raise InputError(
            f"{name} has {values.shape[0]} frames; the segments reach frame "
            f"{int(segments.frame.max())}"
        )


def linear_slerp(
    quat: np.ndarray,
    trans: np.ndarray,
    segments: SegmentMap,
    euler_order: EulerOrder = "XYZ",
    truth_euler: np.ndarray | None = None,
) -> Reconstruction:
    """Linear translation + quaternion SLERP between keyframes (§3.1, Eq. 2.5–2.6).

    Args:
        quat: (F, J, 4) wxyz rotations of the motion the map indexes (any sign convention:
            SLERP takes the shorter arc).
        trans: (F, 3) root translation in metres.
        segments: which frames to reconstruct, from which keyframes.
        euler_order: the store's Euler order (``motion/euler`` attrs) for the euler75 layout.
        truth_euler: optional (F, J, 3) stored Euler angles, for exact keyframe rows.

    Returns:
        A :class:`Reconstruction` of the segment map's frames; keyframe rows equal the input.
    """
    # Gather first, convert after: the inputs may be a whole store's float32 arrays.
    quat, trans = np.asarray(quat), np.asarray(trans)
    _check_frames("quat", quat, segments)
    _check_frames("trans", trans, segments)
    u = segments.u
    q = slerp(_rows(quat, segments.left), _rows(quat, segments.right), u[:, None])
    t = (1.0 - u)[:, None] * _rows(trans, segments.left) + u[:, None] * _rows(trans, segments.right)
    keep = segments.is_keyframe
    q[keep] = _rows(quat, segments.frame[keep])
    t[keep] = _rows(trans, segments.frame[keep])
    truth = None
    if truth_euler is not None:
        truth = _rows(np.asarray(truth_euler), segments.frame)
    return Reconstruction(segments, t, euler_order, quat=q, truth_euler=truth)
