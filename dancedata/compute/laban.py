"""Laban efforts of joint trajectories (pure functions; axis 0 = time, positions in metres).

Larboulette & Gibet (2015), "A review of computable expressive descriptors of human motion"
(MOCO '15), define the four Laban efforts over a time window T of frames t1..tT, for joints k
with weights α_k (here α_k = 1, so the summed effort is the plain sum over joints):

* **Weight** (strong/light): the peak kinetic energy Σ_k α_k |v_k(t)|². dancedata's
  ``weight_effort`` (``compute.motion_features.weight_effort``) is the genre thesis' variant, the
  summed joint *angular* speed; it stays the stored Weight.
* **Time** (sudden/sustained): E_time = (1/T) Σ_t Σ_k α_k |a_k(t)|, the mean acceleration
  magnitude (m/s²).
* **Space** (direct/indirect): E_space = Σ_k α_k · Σ_t |x_k(t+1) − x_k(t)| / |x_k(tT) − x_k(t1)|,
  path length over net displacement (dimensionless, ≥ 1; 1 is a straight line).
* **Flow** (bound/free): E_flow = (1/T) Σ_t Σ_k α_k |j_k(t)|, the mean jerk magnitude (m/s³).

Every function returns one value per frame and joint: the effort over the window of ``window``
frames centred on that frame (clipped to the clip at its ends), so an effort can be read per
frame, per measure or per sequence. Derivatives are finite differences at ``fps``; a derivative
of order k is defined between frames t and t+k and assigned to the window by its first frame.
"""

from __future__ import annotations

import numpy as np

__all__ = [
    "SPACE_FLOOR_M",
    "effort_summary",
    "laban_flow",
    "laban_space",
    "laban_time",
    "window_frames",
]

# Net displacements below this (metres) count as "no net movement": Space is path / max(net,
# floor), and a joint that moves less than the floor along its path is direct (Space 1).
SPACE_FLOOR_M = 1e-3


def window_frames(window_s: float, fps: float) -> int:
    """Frames in a window of ``window_s`` seconds at ``fps``: odd (centred), at least 3."""
    if not (np.isfinite(window_s) and window_s > 0 and np.isfinite(fps) and fps > 0):
        raise ValueError(f"window_s and fps must be positive and finite, got {window_s}, {fps}")
    n = max(3, int(round(window_s * fps)))
    return n if n % 2 else n + 1


def _check(positions: np.ndarray, window: int) -> np.ndarray:
    p = np.asarray(positions, dtype=np.float64)
    if p.ndim != 3 or p.shape[-1] != 3:
        raise ValueError(f"need positions (F, J, 3), got {p.shape}")
    if window < 1:
        raise ValueError("window must be at least 1 frame")
    return p


def _window_bounds(n: int, window: int) -> tuple[np.ndarray, np.ndarray]:
    """[lo, hi) frame bounds of the window centred on each of n frames, clipped to [0, n)."""
    half = window // 2
    t = np.arange(n)
    return np.maximum(0, t - half), np.minimum(n, t + half + 1)


def _windowed_mean(values: np.ndarray, n_frames: int, window: int) -> np.ndarray:
    """Mean of ``values`` (m, J) over each frame's window, a value at index i standing for the
    derivative that starts at frame i; frames whose window holds none get the nearest one."""
    m = values.shape[0]
    out = np.zeros((n_frames, values.shape[1]))
    if m == 0:
        return out
    lo, hi = _window_bounds(n_frames, window)
    lo = np.minimum(lo, m - 1)
    hi = np.clip(hi, lo + 1, m)
    csum = np.concatenate([np.zeros((1, values.shape[1])), np.cumsum(values, axis=0)])
    return (csum[hi] - csum[lo]) / (hi - lo)[:, None]


def laban_time(positions: np.ndarray, fps: float, *, window: int) -> np.ndarray:
    """(F, J, 3) m → (F, J) Time effort: mean |acceleration| (m/s²) over each frame's window.
    Sum over axis 1 for the whole body's effort."""
    p = _check(positions, window)
    acc = np.linalg.norm(np.diff(p, n=2, axis=0), axis=-1) * fps**2
    return _windowed_mean(acc, p.shape[0], window)


def laban_flow(positions: np.ndarray, fps: float, *, window: int) -> np.ndarray:
    """(F, J, 3) m → (F, J) Flow effort: mean |jerk| (m/s³) over each frame's window."""
    p = _check(positions, window)
    jerk = np.linalg.norm(np.diff(p, n=3, axis=0), axis=-1) * fps**3
    return _windowed_mean(jerk, p.shape[0], window)


def laban_space(positions: np.ndarray, *, window: int) -> np.ndarray:
    """(F, J, 3) m → (F, J) Space effort: path length over net displacement within each frame's
    window (dimensionless, ≥ 1). The net displacement is floored at :data:`SPACE_FLOOR_M`, so a
    joint standing still or returning to its start scores path / floor, and one that moves less
    than the floor in all scores 1 (direct)."""
    p = _check(positions, window)
    n = p.shape[0]
    step = np.linalg.norm(np.diff(p, axis=0), axis=-1)  # (F−1, J)
    path_sum = np.concatenate([np.zeros((1, p.shape[1])), np.cumsum(step, axis=0)])
    lo, hi = _window_bounds(n, window)
    last = hi - 1
    path = path_sum[last] - path_sum[lo]
    net = np.linalg.norm(p[last] - p[lo], axis=-1)
    space = path / np.maximum(net, SPACE_FLOOR_M)
    return np.where(path < SPACE_FLOOR_M, 1.0, np.maximum(space, 1.0))


def effort_summary(efforts: dict[str, np.ndarray]) -> dict[str, float]:
    """Per-sequence summary of per-frame efforts: for each name, the mean over frames of the
    effort summed over joints ((F, J) arrays) or of the value itself ((F,) arrays)."""
    out: dict[str, float] = {}
    for name, values in efforts.items():
        v = np.asarray(values, dtype=np.float64)
        out[name] = float((v.sum(axis=1) if v.ndim == 2 else v).mean()) if v.size else float("nan")
    return out
