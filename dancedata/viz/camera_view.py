"""Orthographic cameras for skeleton videos: which world axes point right and up on screen.

Conventions (pixels: origin at the top-left corner, x right, y down, as in OpenCV and every video
frame):

* **World 3-d joints** (AIST++ keypoints3d and SMPL joints: y-up, metres; BVH: usually y-up,
  metres in a store; 3-d joints from video CSV: camera frame, ``-y`` up). The store's
  ``motion`` attrs ``up_axis`` names the up axis (``x``, ``y``, ``z``, optionally with a sign).
  With U the unit up vector, the *front* camera sits on the side D_front of the scene and looks
  back at it, where D_front is +z for y-up, -y for z-up, +y for x-up (and the negated vector for
  a negative up axis, so a right-handed frame stays right-handed); screen right is ``U × D``,
  screen up is U. The *side* camera sits on the front camera's right (D = right_front) and the
  *top* camera above (D = U), with the front camera's side of the scene at the bottom of the
  screen (screen up = -D_front). Projection is orthographic: depth is dropped.
* **Image 2-d joints** (video poses, ``motion/pose2d``: pixels of the source video, x right,
  y down): drawn as the camera saw them, only scaled and shifted; y is not flipped. Only the
  front view exists.

A camera is fitted once per sequence to the bounding box of all its frames (NaN ignored), so the
figure moves inside a still frame, with a uniform scale (no distortion) and a margin.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from dancedata.errors import InputError

__all__ = ["VIEWS", "ViewCamera", "fit_camera", "project", "screen_axes"]

VIEWS = ("front", "side", "top")
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
    """(2, 3) world vectors that point right and up on screen for ``view`` (module docstring)."""
    if view not in VIEWS:
        raise InputError(f"view must be one of {', '.join(VIEWS)}, not {view!r}")
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


def project(camera: ViewCamera, points: np.ndarray) -> np.ndarray:
    """(..., 2) float64 pixel coordinates (x, y) of (..., D) points; NaN stays NaN."""
    plane = _plane(points, camera.basis) - camera.centre
    plane[..., 1] *= camera.y_sign
    return camera.centre_px + camera.scale * plane


def fit_camera(
    points: np.ndarray,
    kind: str,
    up_axis: str,
    view: str,
    area: tuple[int, int, int, int],
    margin: float = 0.08,
) -> ViewCamera:
    """The camera showing every finite point of ``points`` (F, J, D) inside ``area``.

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
