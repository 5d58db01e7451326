"""Synthetic AIST++ keypoint annotations from synthetic joint positions.

Pure functions, float arrays in and out. ``keypoints3d`` (triangulated, with gaps) and
``keypoints3d_optim`` (smooth, complete) in cm; ``keypoints2d`` by projecting the clean 3-d
keypoints through the setting's cameras (OpenCV model with distortion) plus detector noise,
with per-view detection drop-outs; ``det_scores``; ``timestamps`` in µs at 60 fps.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from dancedata.compute.camera import project_points
from dancedata.synth.cameras import camera_arrays

DETECTION_NOISE_PX = 1.5
TRIANGULATION_NOISE_CM = 0.3


def _gap(n_frames: int, rng: np.random.Generator, shortest: int, longest: int) -> slice:
    length = int(rng.integers(shortest, min(longest, max(shortest + 1, n_frames // 4)) + 1))
    start = int(rng.integers(0, max(1, n_frames - length)))
    return slice(start, start + length)


def synth_keypoints3d(keypoints_cm: np.ndarray, rng: np.random.Generator) -> dict[str, Any]:
    """``keypoints3d`` (noisy; in a third of the sequences a run of 5–30 all-NaN frames, as
    where AIST++ triangulation failed) and ``keypoints3d_optim`` = the clean keypoints, both
    (F, 17, 3) float64 cm."""
    raw = keypoints_cm + rng.normal(0.0, TRIANGULATION_NOISE_CM, keypoints_cm.shape)
    if rng.random() < 1 / 3 and keypoints_cm.shape[0] > 40:
        raw[_gap(keypoints_cm.shape[0], rng, 5, 30)] = np.nan
    return {
        "keypoints3d": raw.astype(np.float64),
        "keypoints3d_optim": np.asarray(keypoints_cm, dtype=np.float64),
    }


def synth_keypoints2d(
    keypoints_cm: np.ndarray, cameras: list[dict[str, Any]], rng: np.random.Generator, fps: float
) -> dict[str, np.ndarray]:
    """AIST++ ``keypoints2d`` (V, F, 17, 3) float32 (x, y pixels, confidence), ``det_scores``
    (V, F) float32 and ``timestamps`` (F,) int64 µs for the clean keypoints (F, 17, 3) in cm."""
    params = camera_arrays(cameras)
    uv = project_points(
        keypoints_cm,
        params["intrinsics"],
        params["rvec"],
        params["translation"],
        params["distortions"],
        dtype=np.float32,  # ~1e-4 px off: nothing next to the 1.5 px detector noise
    )  # (V, F, 17, 2)
    n_views, n_frames = uv.shape[:2]
    keypoints = np.empty((*uv.shape[:-1], 3), dtype=np.float32)
    noise = rng.standard_normal(uv.shape, dtype=np.float32)
    keypoints[..., :2] = uv + DETECTION_NOISE_PX * noise
    keypoints[..., 2] = 0.55 + 0.4 * rng.random(uv.shape[:-1], dtype=np.float32)
    scores = 0.35 + 0.4 * rng.random((n_views, n_frames), dtype=np.float32)
    if n_frames > 40:
        view = int(rng.integers(n_views))
        keypoints[view, _gap(n_frames, rng, 3, 20)] = np.nan  # the detector lost the dancer
    return {
        "keypoints2d": keypoints,
        "det_scores": scores,
        "timestamps": np.round(np.arange(n_frames) * 1e6 / fps).astype(np.int64),
    }
