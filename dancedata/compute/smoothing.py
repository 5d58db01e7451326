"""Zero-phase Butterworth low-pass smoothing of motion curves (axis 0 = time).

The filter runs forward and backward (scipy ``sosfiltfilt``), so it adds no lag; the effective
order is twice ``order`` and the gain at ``cutoff_hz`` is 1/2 (−6 dB). The thesis smooths with
order 1-2.

Rotations need care: a filter sees a jump from +179° to −179° (or from q to −q) as a huge step
and rings around it. So Euler curves are unwrapped before filtering and wrapped back after, and
quaternion curves are made sign-continuous, filtered per component, then renormalised.
"""

from __future__ import annotations

import numpy as np

from dancedata.compute.rotations import quat_sign_continuous

__all__ = ["butterworth_lowpass", "smooth_euler", "smooth_quaternions"]


def butterworth_lowpass(
    x: np.ndarray, fps: float, cutoff_hz: float, order: int = 2, axis: int = 0
) -> np.ndarray:
    """Zero-phase Butterworth low-pass of ``x`` along ``axis`` (sampled at ``fps`` Hz).

    Odd-extension padding as scipy's default, shortened for clips shorter than the default
    pad; clips of fewer than 2 frames are returned unchanged.
    """
    if not 0 < cutoff_hz < fps / 2:
        raise ValueError(f"cutoff {cutoff_hz} Hz must lie between 0 and fps/2 = {fps / 2} Hz")
    if order < 1:
        raise ValueError(f"order must be at least 1, got {order}")
    # imported here, not with the module: scipy.signal (and the scipy.stats it imports) takes
    # ~0.4-0.8 s to import, which every BVH or generated-motion ingest paid without smoothing
    from scipy.signal import butter, sosfiltfilt

    x = np.asarray(x, dtype=np.float64)
    n = x.shape[axis]
    if n < 2:
        return x.copy()
    sos = butter(order, cutoff_hz, btype="low", fs=fps, output="sos")
    zeros_b = int((sos[:, 2] == 0).sum())
    zeros_a = int((sos[:, 5] == 0).sum())
    default_pad = 3 * (2 * len(sos) + 1 - min(zeros_b, zeros_a))
    return sosfiltfilt(sos, x, axis=axis, padlen=min(default_pad, n - 1))


def smooth_quaternions(
    quat: np.ndarray, fps: float, cutoff_hz: float, order: int = 2
) -> np.ndarray:
    """Low-pass (F, ..., 4) unit quaternions: signs made continuous over time (q and −q are the
    same rotation), each component filtered, the result renormalised. The output keeps the
    continuous signs."""
    quat = np.asarray(quat, dtype=np.float64)
    lead = quat.shape
    flat = quat.reshape(lead[0], -1, 4)
    smooth = butterworth_lowpass(quat_sign_continuous(flat), fps, cutoff_hz, order)
    smooth /= np.linalg.norm(smooth, axis=-1, keepdims=True)
    return smooth.reshape(lead)


def smooth_euler(
    euler_rad: np.ndarray, fps: float, cutoff_hz: float, order: int = 2, wrap: bool = True
) -> np.ndarray:
    """Low-pass Euler angle curves (F, ..., 3) in radians: unwrapped over time first, so
    crossing ±π is not a jump; wrapped back to [−π, π) when ``wrap``. For angles converted
    from matrices, make branches continuous first
    (:func:`dancedata.compute.euler_continuity.euler_continuous`)."""
    unwrapped = np.unwrap(np.asarray(euler_rad, dtype=np.float64), axis=0)
    smooth = butterworth_lowpass(unwrapped, fps, cutoff_hz, order)
    return (smooth + np.pi) % (2 * np.pi) - np.pi if wrap else smooth


def smooth_axis_angle(
    axis_angle: np.ndarray, fps: float, cutoff_hz: float, order: int = 2
) -> np.ndarray:
    """Low-pass (F, ..., 3) joint rotations given as axis-angle (radians): converted to unit
    quaternions (wxyz), smoothed by :func:`smooth_quaternions` (sign-continuous over time,
    per component, renormalised), converted back (angles in [0, π])."""
    from dancedata.compute.rotations import axis_angle_to_quat, quat_to_axis_angle

    quat = axis_angle_to_quat(np.asarray(axis_angle, dtype=np.float64))
    return quat_to_axis_angle(smooth_quaternions(quat, fps, cutoff_hz, order))


def butterworth_gain(freq_hz: np.ndarray, fps: float, cutoff_hz: float, order: int) -> np.ndarray:
    """Closed-form magnitude response of :func:`butterworth_lowpass` (forward and backward):
    |H|² of the digital Butterworth filter made by the bilinear transform,
    1 / (1 + (tan(π f / fps) / tan(π f_c / fps))^(2·order)); 1/2 at the cutoff."""
    ratio = np.tan(np.pi * np.asarray(freq_hz, dtype=np.float64) / fps) / np.tan(
        np.pi * cutoff_hz / fps
    )
    return 1.0 / (1.0 + ratio ** (2 * order))
