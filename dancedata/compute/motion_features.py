"""Motion features and scores (pure functions; axis 0 = time).

* Derivatives of positions: velocity, acceleration, jerk (finite differences, units/s^n).
* Angular velocity from quaternions, ω = 2·q̇·q̄ (rad/s), its derivatives (angular acceleration
  rad/s², angular jerk rad/s³), and the Laban "weight effort" (sum of joint angular speeds) used
  by the genre-based dance generation thesis. Time, Space and Flow are in ``compute.laban``.
* Motion beats and beat-alignment scores in the two flavours in circulation. They give
  *different numbers* and are named after the code bases that define them:
    - ``mint`` (FACT / AIST++): beats are ``argrelextrema(order=10)`` minima of the summed joint
      speed; score = mean over *motion* beats of exp(−d²/(2σ²)), d = frames to the nearest
      music beat, σ = 3.
    - ``bailando``: beats are minima of the mean joint speed smoothed by a Gaussian (σ = 5);
      score = mean over *music* beats of exp(−d²/(2σ²)), d = frames to the nearest motion beat.
* Kinetic (3 per joint, 72-d for SMPL-24) and geometric (32-d, Müller et al. 2005) features as
  computed by the AIST++ / Bailando FID code, for SMPL-24 joint positions in metres, y up.
"""

from __future__ import annotations

from typing import Literal

import numpy as np

__all__ = [
    "SMPL_JOINT_NAMES",
    "acceleration",
    "angular_acceleration",
    "angular_jerk",
    "angular_velocity",
    "beat_align_score_bailando",
    "beat_align_score_mint",
    "geometric_feature_frames",
    "geometric_features",
    "jerk",
    "kinetic_features",
    "motion_beats_bailando",
    "motion_beats_mint",
    "motion_envelope_bailando",
    "motion_envelope_mint",
    "velocity",
    "weight_effort",
]


# --------------------------------------------------------------------------------------------
# Derivatives


def velocity(x: np.ndarray, fps: float) -> np.ndarray:
    """(F, ...) → (F−1, ...) forward differences × fps (units per second)."""
    return np.diff(np.asarray(x, dtype=np.float64), n=1, axis=0) * fps


def acceleration(x: np.ndarray, fps: float) -> np.ndarray:
    """(F, ...) → (F−2, ...) second differences × fps² (units per second²)."""
    return np.diff(np.asarray(x, dtype=np.float64), n=2, axis=0) * fps**2


def jerk(x: np.ndarray, fps: float) -> np.ndarray:
    """(F, ...) → (F−3, ...) third differences × fps³ (units per second³)."""
    return np.diff(np.asarray(x, dtype=np.float64), n=3, axis=0) * fps**3


def _quat_mul(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Hamilton product of wxyz quaternions."""
    aw, ax, ay, az = np.moveaxis(a, -1, 0)
    bw, bx, by, bz = np.moveaxis(b, -1, 0)
    return np.stack(
        [
            aw * bw - ax * bx - ay * by - az * bz,
            aw * bx + ax * bw + ay * bz - az * by,
            aw * by - ax * bz + ay * bw + az * bx,
            aw * bz + ax * by - ay * bx + az * bw,
        ],
        axis=-1,
    )


def angular_velocity(quat: np.ndarray, fps: float) -> np.ndarray:
    """(F, ..., 4) wxyz unit quaternions → (F−1, ..., 3) angular velocity in rad/s.

    ω = vector part of 2·Δq·q̄ with Δq = (q[t+1] − q[t])·fps and q̄ the conjugate of q[t]; signs
    are made continuous first (q and −q are one rotation). For local joint rotations ω is
    expressed in the parent's frame. First order: the error grows with the square of the
    rotation per frame (about 0.1 % at 5° per frame).
    """
    q = np.asarray(quat, dtype=np.float64)
    if q.shape[0] < 2:
        return np.zeros((0,) + q.shape[1:-1] + (3,))
    flat = q.reshape(q.shape[0], -1, 4)
    dots = np.sum(flat[1:] * flat[:-1], axis=-1)
    flips = np.cumsum(dots < 0, axis=0) % 2 == 1
    flat = flat.copy()
    flat[1:][flips] *= -1.0
    q = flat.reshape(q.shape)
    dq = (q[1:] - q[:-1]) * fps
    conj = q[:-1] * np.array([1.0, -1.0, -1.0, -1.0])
    return 2.0 * _quat_mul(dq, conj)[..., 1:]


def angular_acceleration(quat: np.ndarray, fps: float) -> np.ndarray:
    """(F, ..., 4) wxyz → (F−2, ..., 3) angular acceleration (rad/s²): forward differences of
    :func:`angular_velocity` × fps, in the same (parent) frame."""
    omega = angular_velocity(quat, fps)
    return np.diff(omega, n=1, axis=0) * fps


def angular_jerk(quat: np.ndarray, fps: float) -> np.ndarray:
    """(F, ..., 4) wxyz → (F−3, ..., 3) angular jerk (rad/s³): second forward differences of
    :func:`angular_velocity` × fps²."""
    omega = angular_velocity(quat, fps)
    return np.diff(omega, n=2, axis=0) * fps**2


def weight_effort(quat: np.ndarray, fps: float) -> np.ndarray:
    """(F, J, 4) wxyz → (F−1,) Laban weight effort: Σ over joints of |ω| (rad/s)."""
    return (
        np.linalg.norm(angular_velocity(quat, fps), axis=-1)
        .reshape(max(np.shape(quat)[0] - 1, 0), -1)
        .sum(axis=1)
    )


# --------------------------------------------------------------------------------------------
# Motion beats and beat alignment


def motion_envelope_mint(positions: np.ndarray) -> np.ndarray:
    """(F, J, 3) → (F,) summed joint displacement per frame, frame 0 set to 0 (mint: the
    displacement *arriving* at frame t)."""
    p = np.asarray(positions, dtype=np.float64)
    env = np.zeros(p.shape[0])
    env[1:] = np.linalg.norm(p[1:] - p[:-1], axis=-1).sum(axis=1)
    return env


def motion_beats_mint(positions: np.ndarray, order: int = 10) -> np.ndarray:
    """Motion-beat frame indices, mint/FACT variant: strict local minima of
    :func:`motion_envelope_mint` over ±``order`` frames (10 at 60 fps)."""
    from scipy.signal import argrelextrema  # here: scipy.signal costs 0.4 s to import

    return argrelextrema(motion_envelope_mint(positions), np.less, order=order)[0]


def motion_envelope_bailando(positions: np.ndarray, sigma: float = 5.0) -> np.ndarray:
    """(F, J, 3) → (F−1,) mean joint displacement between frames t and t+1, Gaussian-smoothed
    with ``sigma`` frames (Bailando)."""
    from scipy.ndimage import gaussian_filter1d  # here: 0.2 s to import, rarely needed

    p = np.asarray(positions, dtype=np.float64)
    speed = np.linalg.norm(p[1:] - p[:-1], axis=-1).mean(axis=1)
    return gaussian_filter1d(speed, sigma) if len(speed) else speed


def motion_beats_bailando(positions: np.ndarray, sigma: float = 5.0) -> np.ndarray:
    """Motion-beat indices, Bailando variant: strict local minima (±1 frame) of
    :func:`motion_envelope_bailando`. Index t refers to the step from frame t to t+1."""
    from scipy.signal import argrelextrema

    return argrelextrema(motion_envelope_bailando(positions, sigma), np.less)[0]


def _nearest_distance(points: np.ndarray, targets: np.ndarray) -> np.ndarray:
    """For each point, the distance (frames) to the nearest target; targets need not be sorted."""
    targets = np.sort(np.asarray(targets, dtype=np.float64))
    points = np.asarray(points, dtype=np.float64)
    idx = np.searchsorted(targets, points)
    left = targets[np.clip(idx - 1, 0, len(targets) - 1)]
    right = targets[np.clip(idx, 0, len(targets) - 1)]
    return np.minimum(np.abs(points - left), np.abs(points - right))


def beat_align_score_mint(
    music_beats: np.ndarray, motion_beats: np.ndarray, sigma: float = 3.0
) -> float:
    """mint/FACT beat-alignment score: mean over *motion* beats of exp(−d²/(2σ²)), d = frames to
    the nearest music beat. 0.0 when there are no motion beats (as the reference)."""
    motion_beats = np.asarray(motion_beats)
    if motion_beats.size == 0:
        return 0.0
    if np.size(music_beats) == 0:
        raise ValueError("no music beats to align to")
    d = _nearest_distance(motion_beats, music_beats)
    return float(np.mean(np.exp(-(d**2) / (2 * sigma**2))))


def beat_align_score_bailando(
    music_beats: np.ndarray,
    motion_beats: np.ndarray,
    sigma: float = 3.0,
    n_frames: int | None = None,
) -> float:
    """Bailando beat-alignment score: mean over *music* beats of exp(−d²/(2σ²)) (σ² = 9, the
    "exp(−d²/18)" of the paper), d = frames to the nearest motion beat. Bailando keeps only music
    beats before the motion envelope's length: pass ``n_frames`` (F−1 for F motion frames) to do
    the same. NaN without music beats; 0.0 without motion beats."""
    music_beats = np.asarray(music_beats)
    if n_frames is not None:
        music_beats = music_beats[music_beats < n_frames]
    if music_beats.size == 0:
        return float("nan")
    if np.size(motion_beats) == 0:
        return 0.0
    d = _nearest_distance(music_beats, motion_beats)
    return float(np.mean(np.exp(-(d**2) / (2 * sigma**2))))


# --------------------------------------------------------------------------------------------
# Kinetic features


def kinetic_features(
    positions: np.ndarray,
    fps: float,
    *,
    mode: Literal["parity", "corrected"],
    up_axis: Literal["y", "z"] = "y",
    window: int = 2,
) -> np.ndarray:
    """(F, J, 3) joint positions → (3J,) kinetic features, per joint [horizontal kinetic energy,
    vertical kinetic energy, energy expenditure] (72-d for SMPL-24; float64).

    For frames i = 1..F−1 the velocity is the mean of the displacements ``p[k] − p[k−1]`` for k
    within ±``window`` of i (clipped to the clip) divided by the frame time; kinetic energies are
    the mean over i of the squared horizontal / vertical speed (per unit mass, no ½). Energy
    expenditure is the mean over i of |mean acceleration| over the same window.

    ``mode="parity"`` reproduces the AIST++/Bailando code bit for bit, including its operator
    precedence slip ``v1 = p[k] − p[k−1] / dt``; published FID_k numbers use it. ``"corrected"``
    uses ``v1 = (p[k] − p[k−1]) / dt``, i.e. acceleration (p[k+1] − 2p[k] + p[k−1]) / dt².
    The reference defaults are fps = 60, y up, window 2.
    """
    if mode not in ("parity", "corrected"):
        raise ValueError(f"mode must be 'parity' or 'corrected', got {mode!r}")
    if up_axis not in ("y", "z"):
        raise ValueError(f"up_axis must be 'y' or 'z', got {up_axis!r}")
    if window < 1:
        raise ValueError("window must be at least 1")
    p = np.asarray(positions, dtype=np.float64)
    n = p.shape[0]
    if p.ndim != 3 or p.shape[2] != 3 or n < 3:
        raise ValueError(f"need positions (F >= 3, J, 3), got {p.shape}")
    dt = 1.0 / fps
    i = np.arange(1, n)

    # Velocity window: displacements k in [max(1, i−w), min(F−1, i+w)].
    disp = np.concatenate([np.zeros((1,) + p.shape[1:]), np.cumsum(p[1:] - p[:-1], axis=0)])
    lo = np.maximum(1, i - window)
    hi = np.minimum(n - 1, i + window)
    count = (hi - lo + 1)[:, None, None]
    vel = (disp[hi] - disp[lo - 1]) / (count * dt)  # (F−1, J, 3)
    up = 1 if up_axis == "y" else 2
    horizontal = [a for a in (0, 1, 2) if a != up]
    ke_h = np.sum(vel[..., horizontal] ** 2, axis=-1).sum(axis=0) / (n - 1.0)
    ke_v = (vel[..., up] ** 2).sum(axis=0) / (n - 1.0)

    # Acceleration window: k in [max(1, i−w), min(F−2, i+w)].
    k = np.arange(1, n - 1)
    v2 = (p[k + 1] - p[k]) / dt
    v1 = (p[k] - p[k - 1]) / dt if mode == "corrected" else p[k] - p[k - 1] / dt
    acc = (v2 - v1) / dt  # acc[m] belongs to k = m + 1
    acc_sum = np.concatenate([np.zeros((1,) + p.shape[1:]), np.cumsum(acc, axis=0)])
    lo_a = np.maximum(1, i - window)
    hi_a = np.minimum(n - 2, i + window)
    count_a = (hi_a - lo_a + 1)[:, None, None]
    mean_acc = (acc_sum[hi_a] - acc_sum[lo_a - 1]) / count_a
    expenditure = np.linalg.norm(mean_acc, axis=-1).sum(axis=0) / (n - 1.0)

    return np.stack([ke_h, ke_v, expenditure], axis=1).reshape(-1)


# --------------------------------------------------------------------------------------------
# Geometric features

SMPL_JOINT_NAMES = (
    "root", "lhip", "rhip", "belly", "lknee", "rknee", "spine", "lankle", "rankle", "chest",
    "ltoes", "rtoes", "neck", "linshoulder", "rinshoulder", "head", "lshoulder", "rshoulder",
    "lelbow", "relbow", "lwrist", "rwrist", "lhand", "rhand",
)  # fmt: skip
_J = {name: i for i, name in enumerate(SMPL_JOINT_NAMES)}

# Body dimensions (metres) from the SMPL neutral rest pose, as the reference computes them:
# humerus = |lshoulder − lelbow|, shoulder width = |lshoulder − rshoulder|, hip width =
# |lhip − rhip|; about 0.25684, 0.39085 and 0.11925.
_LSHOULDER = np.array([1.99113488e-01, 2.36807942e-01, -1.80702247e-02])
_LELBOW = np.array([4.54445392e-01, 2.21158922e-01, -4.10167128e-02])
_RSHOULDER = np.array([-1.91692337e-01, 2.36928746e-01, -1.23055102e-02])
_LHIP = np.array([5.64076714e-02, -3.23069185e-01, 1.09197125e-02])
_RHIP = np.array([-6.24834076e-02, -3.31302464e-01, 1.50412619e-02])
HUMERUS_M = float(np.linalg.norm(_LSHOULDER - _LELBOW))
SHOULDER_WIDTH_M = float(np.linalg.norm(_LSHOULDER - _RSHOULDER))
HIP_WIDTH_M = float(np.linalg.norm(_LHIP - _RHIP))

_HL, _SW, _HW = HUMERUS_M, SHOULDER_WIDTH_M, HIP_WIDTH_M
# The 32 predicates, in the reference order: (kind, joints, threshold or angle range).
_PREDICATES: tuple[tuple[str, tuple[str, ...], float | tuple[float, float]], ...] = (
    ("nmove", ("neck", "rhip", "lhip", "rwrist"), 1.8 * _HL),
    ("nmove", ("neck", "lhip", "rhip", "lwrist"), 1.8 * _HL),
    ("nplane", ("chest", "neck", "neck", "rwrist"), 0.2 * _HL),
    ("nplane", ("chest", "neck", "neck", "lwrist"), 0.2 * _HL),
    ("move", ("belly", "chest", "chest", "rwrist"), 1.8 * _HL),
    ("move", ("belly", "chest", "chest", "lwrist"), 1.8 * _HL),
    ("angle", ("relbow", "rshoulder", "relbow", "rwrist"), (0, 110)),
    ("angle", ("lelbow", "lshoulder", "lelbow", "lwrist"), (0, 110)),
    ("nplane", ("lshoulder", "rshoulder", "lwrist", "rwrist"), 2.5 * _SW),
    ("move", ("lwrist", "rwrist", "rwrist", "lwrist"), 1.4 * _HL),
    ("move", ("rwrist", "root", "lwrist", "root"), 1.4 * _HL),
    ("move", ("lwrist", "root", "rwrist", "root"), 1.4 * _HL),
    ("fast", ("rwrist",), 2.5 * _HL),
    ("fast", ("lwrist",), 2.5 * _HL),
    ("plane", ("root", "lhip", "ltoes", "rankle"), 0.38 * _HL),
    ("plane", ("root", "rhip", "rtoes", "lankle"), 0.38 * _HL),
    ("nplane", ("zero", "y_unit", "y_min", "rankle"), 1.2 * _HL),
    ("nplane", ("zero", "y_unit", "y_min", "lankle"), 1.2 * _HL),
    ("nplane", ("lhip", "rhip", "lankle", "rankle"), 2.1 * _HW),
    ("angle", ("rknee", "rhip", "rknee", "rankle"), (0, 110)),
    ("angle", ("lknee", "lhip", "lknee", "lankle"), (0, 110)),
    ("fast", ("rankle",), 2.5 * _HL),
    ("fast", ("lankle",), 2.5 * _HL),
    ("angle", ("neck", "root", "rshoulder", "relbow"), (25, 180)),
    ("angle", ("neck", "root", "lshoulder", "lelbow"), (25, 180)),
    ("angle", ("neck", "root", "rhip", "rknee"), (50, 180)),
    ("angle", ("neck", "root", "lhip", "lknee"), (50, 180)),
    ("plane", ("rankle", "neck", "lankle", "root"), 0.5 * _HL),
    ("angle", ("neck", "root", "zero", "y_unit"), (70, 110)),
    ("nplane", ("zero", "minus_y_unit", "y_min", "rwrist"), -1.2 * _HL),
    ("nplane", ("zero", "minus_y_unit", "y_min", "lwrist"), -1.2 * _HL),
    ("fast", ("root",), 2.3 * _HL),
)


def _dot(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    return np.sum(a * b, axis=-1)


def geometric_feature_frames(
    positions: np.ndarray, frame_time_s: float = 1.0 / 120.0
) -> np.ndarray:
    """(F, 24, 3) SMPL-24 positions (metres, y up) → (F−1, 32) bool predicates for frames
    1..F−1 (velocity predicates compare frame t with t−1).

    ``frame_time_s`` divides the velocity predicates; the reference hard-codes 1/120 s although
    AIST++ runs at 60 fps (the default keeps parity; pass 1/fps for physical speeds).
    Degenerate geometry (zero-length directions) makes a predicate False, as NaN does there.
    """
    p = np.asarray(positions, dtype=np.float64)
    if p.ndim != 3 or p.shape[1:] != (24, 3) or p.shape[0] < 2:
        raise ValueError(f"need SMPL-24 positions (F >= 2, 24, 3), got {p.shape}")
    cur, prev = p[1:], p[:-1]
    n = cur.shape[0]
    y_min = np.zeros((n, 3))
    y_min[:, 1] = cur[:, :, 1].min(axis=1)
    special = {
        "zero": np.zeros((n, 3)),
        "y_unit": np.broadcast_to([0.0, 1.0, 0.0], (n, 3)),
        "minus_y_unit": np.broadcast_to([0.0, -1.0, 0.0], (n, 3)),
        "y_min": y_min,
    }

    def at(name: str) -> np.ndarray:
        return special[name] if name in special else cur[:, _J[name]]

    def before(name: str) -> np.ndarray:
        return prev[:, _J[name]]

    out = np.zeros((n, len(_PREDICATES)), dtype=bool)
    with np.errstate(divide="ignore", invalid="ignore"):
        for col, (kind, names, arg) in enumerate(_PREDICATES):
            if kind == "fast":
                speed = np.linalg.norm(at(names[0]) - before(names[0]), axis=-1) / frame_time_s
                out[:, col] = speed > arg
                continue
            j1, j2, j3, j4 = (at(name) for name in names)
            if kind == "move":
                vel = (j3 - j1) - (before(names[2]) - before(names[0]))
                direction = j2 - j1
                along = _dot(vel, direction) / np.linalg.norm(direction, axis=-1)
                out[:, col] = along / frame_time_s > arg
            elif kind == "nmove":
                vel = (j4 - j1) - (before(names[3]) - before(names[0]))
                direction = np.cross(j3 - j1, j2 - j1)
                along = _dot(vel, direction) / np.linalg.norm(direction, axis=-1)
                out[:, col] = along / frame_time_s > arg
            elif kind == "plane":
                normal = np.cross(j3 - j1, j2 - j1)
                dist = _dot(normal, j4 - j1) / np.linalg.norm(normal, axis=-1)
                out[:, col] = dist > arg
            elif kind == "nplane":
                normal = j2 - j1
                dist = _dot(normal, j4 - j3) / np.linalg.norm(normal, axis=-1)
                out[:, col] = dist > arg
            else:  # angle between j2 − j1 and j4 − j3, open range in degrees
                a, b = j2 - j1, j4 - j3
                cos = _dot(a, b) / (np.linalg.norm(a, axis=-1) * np.linalg.norm(b, axis=-1))
                angle = np.degrees(np.arccos(cos))
                assert isinstance(arg, tuple)  # an angle predicate carries (low, high)
                low, high = arg
                out[:, col] = (angle > low) & (angle < high)
    return out


def geometric_features(positions: np.ndarray, frame_time_s: float = 1.0 / 120.0) -> np.ndarray:
    """(F, 24, 3) → (32,) geometric features: each predicate's mean over frames 1..F−1
    (float64; the reference rounds to float32)."""
    return geometric_feature_frames(positions, frame_time_s).mean(axis=0)
