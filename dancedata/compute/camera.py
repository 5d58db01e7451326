"""Pinhole cameras with OpenCV's lens distortion, in numpy (no cv2 needed).

Conventions are OpenCV's: a world point X maps to camera coordinates ``x_c = R X + t``, with R
from a Rodrigues vector (radians); image coordinates are ``K (distort(x_c / z_c))`` in pixels,
with distortion coefficients (k1, k2, p1, p2, k3). t must be in the unit of X (the store keeps
both in metres). All functions are vectorised over leading axes.
"""

from __future__ import annotations

import numpy as np


def rodrigues_to_rotmat(rvec: np.ndarray) -> np.ndarray:
    """(..., 3) Rodrigues vectors (axis × angle, radians) → (..., 3, 3) rotation matrices:
    R = cos θ I + (1 − cos θ) k kᵀ + sin θ [k]×, written out element by element."""
    rvec = np.asarray(rvec, dtype=np.float64)
    theta = np.sqrt(np.sum(rvec * rvec, axis=-1))
    small = theta < 1e-12
    k = rvec / np.where(small, 1.0, theta)[..., None]
    kx, ky, kz = k[..., 0], k[..., 1], k[..., 2]
    c, s = np.cos(theta), np.sin(theta)
    c = np.where(small, 1.0, c)
    v = 1.0 - c
    rot = np.empty((*rvec.shape[:-1], 3, 3))
    rot[..., 0, 0] = c + v * kx * kx
    rot[..., 0, 1] = v * kx * ky - s * kz
    rot[..., 0, 2] = v * kx * kz + s * ky
    rot[..., 1, 0] = v * kx * ky + s * kz
    rot[..., 1, 1] = c + v * ky * ky
    rot[..., 1, 2] = v * ky * kz - s * kx
    rot[..., 2, 0] = v * kx * kz - s * ky
    rot[..., 2, 1] = v * ky * kz + s * kx
    rot[..., 2, 2] = c + v * kz * kz
    return rot


def projection_matrix(
    intrinsics: np.ndarray, rotmat: np.ndarray, translation: np.ndarray
) -> np.ndarray:
    """(..., 3, 4) projection matrices P = K [R | t] (undistorted pinhole): homogeneous pixel
    coordinates of a world point X are P [X; 1]."""
    extrinsics = np.concatenate(
        [np.asarray(rotmat, np.float64), np.asarray(translation, np.float64)[..., :, None]],
        axis=-1,
    )
    return np.asarray(intrinsics, np.float64) @ extrinsics


def project_points(
    points: np.ndarray,
    intrinsics: np.ndarray,
    rvec: np.ndarray,
    translation: np.ndarray,
    distortions: np.ndarray,
    dtype: type = np.float64,
) -> np.ndarray:
    """Pixel coordinates (C, ..., 2) of world points (..., 3) seen by C cameras, as
    ``cv2.projectPoints`` computes them (which ignores K's skew entry; this keeps it).

    ``intrinsics`` (C, 3, 3) pixels, ``rvec`` (C, 3) radians, ``translation`` (C, 3) in the unit
    of ``points``, ``distortions`` (C, 5). Computed in ``dtype`` (float32 is ~1e-4 px off at
    1920 px, plenty for synthetic data). NaN in, NaN out."""
    points = np.asarray(points, dtype=dtype)
    rot = rodrigues_to_rotmat(rvec).astype(dtype)  # (C, 3, 3)
    n_cams = rot.shape[0]
    flat = points.reshape(-1, 3)
    # One matrix product for every camera: columns of (N, 3C) are R_c rows dotted with X.
    cam = (flat @ rot.reshape(n_cams * 3, 3).T).reshape(-1, n_cams, 3)
    cam = np.moveaxis(cam, 1, 0) + np.asarray(translation, dtype)[:, None, :]  # (C, N, 3)
    inv_z = 1.0 / cam[..., 2]
    xd, yd = distort(cam[..., 0] * inv_z, cam[..., 1] * inv_z, distortions)
    k = np.asarray(intrinsics, dtype)[..., None]  # (C, 3, 3, 1) over points
    out = np.empty((n_cams, flat.shape[0], 2), dtype=dtype)
    np.multiply(k[:, 0, 0], xd, out=out[..., 0])
    out[..., 0] += k[:, 0, 2]
    if np.any(k[:, 0, 1]):
        out[..., 0] += k[:, 0, 1] * yd
    np.multiply(k[:, 1, 1], yd, out=out[..., 1])
    out[..., 1] += k[:, 1, 2]
    return out.reshape((n_cams, *points.shape[:-1], 2))


def distort(x: np.ndarray, y: np.ndarray, distortions: np.ndarray) -> tuple[np.ndarray, ...]:
    """OpenCV's radial–tangential model on normalised coordinates x = X/Z, y = Y/Z (arrays of
    shape (C, N)); ``distortions`` (C, 5) = (k1, k2, p1, p2, k3), one row per camera. Returns
    the distorted (x, y) in the dtype of x. Terms whose coefficients are all zero are skipped
    (AIST++ cameras only use k1)."""
    dist = np.asarray(distortions, dtype=x.dtype)[..., None]  # (C, 5, 1) over points
    k1, k2, p1, p2, k3 = (dist[..., i, :] for i in range(5))
    r2 = x * x + y * y
    radial = 1.0 + k1 * r2
    if np.any(k2) or np.any(k3):
        radial += r2 * r2 * (k2 + k3 * r2)
    xd, yd = x * radial, y * radial
    if np.any(p1) or np.any(p2):
        xy = x * y
        xd += 2.0 * p1 * xy + p2 * (r2 + 2.0 * x * x)
        yd += p1 * (r2 + 2.0 * y * y) + 2.0 * p2 * xy
    return xd, yd
