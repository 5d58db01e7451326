"""Resampling motion to another frame rate.

Output frame ``i`` sits at time ``i / dst_fps`` seconds, i.e. at source frame position
``i * src_fps / dst_fps``; only times inside the source clip are produced, so

    n_out = floor((n_in - 1) * dst_fps / src_fps) + 1        (0 when n_in is 0).

When ``src_fps / dst_fps`` is an integer ``k`` (within ``rtol``, because BVH files print the
frame time with few digits: ``.0083333`` s is 120.0005 fps), the motion is decimated exactly:
frames 0, k, 2k, ... are copied bit for bit and ``n_out = floor((n_in - 1) / k) + 1``. Otherwise
rotations are interpolated by SLERP between the two neighbouring source frames (quaternions,
``wxyz``) and translations linearly.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

__all__ = [
    "Resampled",
    "decimation_step",
    "resample_linear",
    "resample_motion",
    "resample_positions",
    "resample_quaternions",
    "resampled_frame_count",
    "slerp",
]

# Output times landing within this many source frames of a source frame count as on it.
_ON_FRAME = 1e-9


def decimation_step(src_fps: float, dst_fps: float, rtol: float = 1e-3) -> int | None:
    """The integer ``k`` with ``src_fps / dst_fps ≈ k`` (relative tolerance ``rtol``), else None.
    ``k = 1`` means the rates are equal."""
    if not (src_fps > 0 and dst_fps > 0):
        raise ValueError(f"frame rates must be positive, got {src_fps} and {dst_fps}")
    ratio = src_fps / dst_fps
    k = round(ratio)
    return k if k >= 1 and abs(ratio - k) <= rtol * ratio else None


def resampled_frame_count(n_frames: int, src_fps: float, dst_fps: float, rtol: float = 1e-3) -> int:
    """Number of output frames (see the module docstring for the formula)."""
    if n_frames <= 0:
        return 0
    k = decimation_step(src_fps, dst_fps, rtol)
    if k is not None:
        return (n_frames - 1) // k + 1
    return math.floor((n_frames - 1) * dst_fps / src_fps + _ON_FRAME) + 1


def resample_positions(
    n_frames: int, src_fps: float, dst_fps: float, rtol: float = 1e-3
) -> np.ndarray:
    """(n_out,) float positions of the output frames on the source frame axis."""
    n_out = resampled_frame_count(n_frames, src_fps, dst_fps, rtol)
    k = decimation_step(src_fps, dst_fps, rtol)
    if k is not None:
        return np.arange(n_out, dtype=np.float64) * k
    return np.minimum(np.arange(n_out) * (src_fps / dst_fps), n_frames - 1.0)


def _neighbours(positions: np.ndarray, n_frames: int) -> tuple[np.ndarray, np.ndarray]:
    """Left source index and fraction in [0, 1] for each position."""
    left = np.floor(positions + _ON_FRAME).astype(np.int64)
    left = np.clip(left, 0, max(n_frames - 2, 0))
    frac = np.clip(positions - left, 0.0, 1.0)
    frac[np.abs(frac) < _ON_FRAME] = 0.0
    return left, frac


def slerp(q0: np.ndarray, q1: np.ndarray, t: np.ndarray) -> np.ndarray:
    """Spherical linear interpolation of unit quaternions (..., 4) by ``t`` (broadcast to the
    leading shape), along the shorter arc. Nearly equal inputs fall back to normalised lerp."""
    q0 = np.asarray(q0, dtype=np.float64)
    q1 = np.asarray(q1, dtype=np.float64)
    t = np.asarray(t, dtype=np.float64)[..., None]
    dot = np.sum(q0 * q1, axis=-1, keepdims=True)
    q1 = np.where(dot < 0, -q1, q1)
    dot = np.clip(np.abs(dot), 0.0, 1.0)
    omega = np.arccos(dot)
    sin_omega = np.sin(omega)
    small = sin_omega < 1e-9
    safe = np.where(small, 1.0, sin_omega)
    w0 = np.where(small, 1.0 - t, np.sin((1.0 - t) * omega) / safe)
    w1 = np.where(small, t, np.sin(t * omega) / safe)
    out = w0 * q0 + w1 * q1
    return out / np.linalg.norm(out, axis=-1, keepdims=True)


def resample_quaternions(quat: np.ndarray, positions: np.ndarray) -> np.ndarray:
    """SLERP (F, ..., 4) quaternions at float source-frame ``positions`` → (N, ..., 4)."""
    quat = np.asarray(quat, dtype=np.float64)
    left, frac = _neighbours(np.asarray(positions, dtype=np.float64), quat.shape[0])
    right = np.minimum(left + 1, quat.shape[0] - 1)
    t = frac.reshape((-1,) + (1,) * (quat.ndim - 2))
    t = np.broadcast_to(t, (len(left),) + quat.shape[1:-1])
    out = slerp(quat[left], quat[right], t)
    exact = frac == 0.0
    out[exact] = quat[left[exact]]
    return out


def resample_linear(values: np.ndarray, positions: np.ndarray) -> np.ndarray:
    """Linear interpolation of (F, ...) values at float source-frame ``positions``."""
    values = np.asarray(values, dtype=np.float64)
    left, frac = _neighbours(np.asarray(positions, dtype=np.float64), values.shape[0])
    right = np.minimum(left + 1, values.shape[0] - 1)
    t = frac.reshape((-1,) + (1,) * (values.ndim - 1))
    out = values[left] * (1.0 - t) + values[right] * t
    exact = frac == 0.0
    out[exact] = values[left[exact]]
    return out


@dataclass(frozen=True)
class Resampled:
    """Result of :func:`resample_motion`.

    Attributes:
        quat: (N, J, 4) wxyz rotations at the new rate.
        translations: resampled translations (N, ...), or None.
        source_positions: (N,) position of each output frame on the source frame axis.
        method: ``"decimate"`` (exact copies of every k-th frame) or ``"slerp"``.
        step: k when decimating, else None.
    """

    quat: np.ndarray
    translations: np.ndarray | None
    source_positions: np.ndarray
    method: str
    step: int | None


def resample_motion(
    quat: np.ndarray,
    translations: np.ndarray | None,
    src_fps: float,
    dst_fps: float,
    rtol: float = 1e-3,
) -> Resampled:
    """Resample rotations (F, J, 4) wxyz and optional translations (F, ...) from ``src_fps`` to
    ``dst_fps``: exact decimation for an integer rate ratio, SLERP + linear otherwise."""
    quat = np.asarray(quat, dtype=np.float64)
    n_frames = quat.shape[0]
    if translations is not None:
        translations = np.asarray(translations, dtype=np.float64)
        if translations.shape[0] != n_frames:
            raise ValueError("quat and translations must have the same number of frames")
    positions = resample_positions(n_frames, src_fps, dst_fps, rtol)
    k = decimation_step(src_fps, dst_fps, rtol)
    if k is not None:
        return Resampled(
            quat=quat[::k].copy(),
            translations=None if translations is None else translations[::k].copy(),
            source_positions=positions,
            method="decimate",
            step=k,
        )
    return Resampled(
        quat=resample_quaternions(quat, positions),
        translations=None if translations is None else resample_linear(translations, positions),
        source_positions=positions,
        method="slerp",
        step=None,
    )
