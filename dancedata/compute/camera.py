"""Every camera's math in one place: pinhole cameras with OpenCV's lens distortion (numpy, no
cv2 needed), the look-at rotation that places one, and the orthographic cameras of the
skeleton videos.

**Pinhole (AIST++ calibrations, synthetic keypoints2d).** Conventions are OpenCV's: a world
point X maps to camera coordinates ``x_c = R X + t``, with R from a Rodrigues vector (radians);
image coordinates are ``K (distort(x_c / z_c))`` in pixels, with distortion coefficients (k1,
k2, p1, p2, k3). t must be in the unit of X (the store keeps both in metres). All functions are
vectorised over leading axes.

**Orthographic (skeleton videos: which world axes point right and up on screen).** Pixels have
their origin at the top-left corner, x right, y down, as in OpenCV and every video frame.

* World 3-d joints (AIST++ keypoints3d and SMPL joints: y-up, metres; BVH: usually y-up,
  metres in a store; 3-d joints from video CSV: camera frame, ``-y`` up). The store's
  ``motion`` attrs ``up_axis`` names the up axis (``x``, ``y``, ``z``, optionally with a sign).
  With U the unit up vector, the *front* camera sits on the side D_front of the scene and looks
  back at it, where D_front is +z for y-up, -y for z-up, +y for x-up (and the negated vector
  for a negative up axis, so a right-handed frame stays right-handed); screen right is
  ``U × D``, screen up is U. The *side* camera sits on the front camera's right
  (D = right_front) and the *top* camera above (D = U), with the front camera's side of the
  scene at the bottom of the screen (screen up = -D_front). Projection is orthographic: depth
  is dropped.
* Image 2-d joints (video poses, ``motion/pose2d``: pixels of the source video, x right,
  y down): drawn as the camera saw them, only scaled and shifted; y is not flipped. Only the
  front view exists.

A view camera is fitted once per sequence to the bounding box of all its frames (NaN ignored),
so the figure moves inside a still frame, with a uniform scale (no distortion) and a margin.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import numpy.typing as npt

from dancedata.errors import InputError


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
    dtype: npt.DTypeLike = np.float64,
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


def look_at(centre: np.ndarray, target: np.ndarray) -> np.ndarray:
    """World → camera rotation (3, 3) of an OpenCV camera (x right, y down, z forward) at
    ``centre`` looking at ``target`` (any one length unit) with the world's +y up in the
    image: rows are the camera's right, down and forward axes in world coordinates."""
    forward = target - centre
    forward = forward / np.linalg.norm(forward)
    right = np.cross(forward, [0.0, 1.0, 0.0])
    right = right / np.linalg.norm(right)
    down = np.cross(forward, right)
    return np.stack([right, down, forward])


# -- orthographic view cameras (skeleton videos) ------------------------------------------------
ORTHO_VIEWS = ("front", "side", "top")
_AXES = {"x": np.array([1.0, 0, 0]), "y": np.array([0, 1.0, 0]), "z": np.array([0, 0, 1.0])}
# The side the front camera looks from, for a positive up axis.
_FRONT_FROM = {"y": np.array([0, 0, 1.0]), "z": np.array([0, -1.0, 0]), "x": np.array([0, 1.0, 0])}


def _parse_up(up_axis: str) -> tuple[str, float]:
    text = (up_axis or "y").strip().lower()
    sign = -1.0 if text.startswith("-") else 1.0
    axis = text.lstrip("+-")
    if axis not in _AXES:
        raise InputError(f"up axis must be x, y or z with an optional sign, not {up_axis!r}")
    return axis, sign


def screen_axes(up_axis: str, view: str) -> np.ndarray:
    """(2, 3) world unit vectors that point right and up on screen for ``view`` (front, side or
    top) of a scene whose up axis is ``up_axis`` (module docstring)."""
    if view not in ORTHO_VIEWS:
        raise InputError(f"view must be one of {', '.join(ORTHO_VIEWS)}, not {view!r}")
    axis, sign = _parse_up(up_axis)
    up = sign * _AXES[axis]
    front_from = sign * _FRONT_FROM[axis]
    right = np.cross(up, front_from)
    if view == "front":
        return np.stack([right, up])
    if view == "side":
        return np.stack([np.cross(up, right), up])
    screen_up = -front_from  # top: looking down along -U
    return np.stack([np.cross(screen_up, up), screen_up])


@dataclass(frozen=True)
class ViewCamera:
    """Maps joint coordinates to pixels: ``px = c_px + s · (B p - c_world) · (1, y_sign)``.

    Attributes:
        basis: (2, D) rows: the coordinate combinations shown right and up (world: screen
            axes; image: the identity, x and y).
        y_sign: -1 for world cameras (screen y grows downward, world up upward), +1 for image
            coordinates (already y-down).
        scale: pixels per unit (metres, or source pixels).
        centre: (2,) screen-plane coordinates shown at ``centre_px``.
        centre_px: (2,) pixel position (x, y) of the panel's drawing area centre.
        kind: "world" or "image".
    """

    basis: np.ndarray
    y_sign: float
    scale: float
    centre: np.ndarray
    centre_px: np.ndarray
    kind: str


def _plane(points: np.ndarray, basis: np.ndarray) -> np.ndarray:
    return np.asarray(points, dtype=np.float64)[..., : basis.shape[1]] @ basis.T


def project_orthographic(camera: ViewCamera, points: np.ndarray) -> np.ndarray:
    """(..., 2) float64 pixel coordinates (x, y) of (..., D) points; NaN stays NaN."""
    plane = _plane(points, camera.basis) - camera.centre
    plane[..., 1] *= camera.y_sign
    return camera.centre_px + camera.scale * plane


def fit_view_camera(
    points: np.ndarray,
    kind: str,
    up_axis: str,
    view: str,
    area: tuple[int, int, int, int],
    margin: float = 0.08,
) -> ViewCamera:
    """The orthographic camera showing every finite point of ``points`` (F, J, D) inside
    ``area``, with one scale for both screen axes.

    Args:
        kind: "world" (3-d joints, up axis ``up_axis``) or "image" (2-d pixels, y down).
        view: front, side or top (image: front only).
        area: (x0, y0, width, height) of the drawing area in pixels.
        margin: fraction of the area left free on each side.

    Raises:
        InputError: on an unknown view or up axis, a side/top view of 2-d poses, or no finite
            point at all.
    """
    if kind == "image":
        if view != "front":
            raise InputError(
                f"2-d poses from video have only the camera's own view, not {view!r}: use "
                "--view front"
            )
        basis, y_sign = np.eye(2), 1.0
    elif kind == "world":
        basis, y_sign = screen_axes(up_axis, view), -1.0
    else:
        raise ValueError(f"kind must be 'world' or 'image', not {kind!r}")
    plane = _plane(points, basis).reshape(-1, 2)
    plane = plane[np.isfinite(plane).all(axis=1)]
    if plane.size == 0:
        raise InputError("the motion has no finite joint position to draw")
    lo, hi = plane.min(axis=0), plane.max(axis=0)
    span = np.maximum(hi - lo, 1e-6)
    x0, y0, width, height = area
    usable = np.array([width, height], dtype=np.float64) * (1.0 - 2.0 * margin)
    scale = float(np.min(usable / span))
    return ViewCamera(
        basis=basis,
        y_sign=y_sign,
        scale=scale,
        centre=(lo + hi) / 2.0,
        centre_px=np.array([x0 + width / 2.0, y0 + height / 2.0]),
        kind=kind,
    )
