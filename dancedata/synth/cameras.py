"""Synthetic AIST++ camera settings: 9 calibrated cameras in a ring around the dance floor.

Pure functions; the camera math (:func:`~dancedata.compute.camera.look_at`) is in
:mod:`dancedata.compute.camera`. The output is what ``cameras/<setting>.json`` holds in
AIST++: per camera ``name``, ``size`` [1920, 1080], ``matrix`` (3×3, pixels), ``distortions``
(k1, k2, p1, p2, k3), ``rotation`` (Rodrigues, world → camera) and ``translation`` in
**centimetres** (the AIST++ unit), with numbers in the real range (cameras 4.3–5 m away at
1.5–2 m height, focal 1300–1650 px, small radial distortion). World is y-up; cameras follow
OpenCV (x right, y down, z forward).
"""

from __future__ import annotations

from typing import Any

import numpy as np
from scipy.spatial.transform import Rotation

from dancedata.compute.camera import look_at

N_CAMERAS = 9
IMAGE_SIZE = (1920, 1080)
# Where the synthetic dancer moves (synth.choreography: steps around x = 0, z = 0.6 m, pulled
# back there), in cm: the point the cameras aim at.
FLOOR_TARGET_CM = np.array([0.0, 90.0, 60.0])


def setting_name(genre_index: int) -> str:
    """Synthetic camera setting of a genre: one setting per genre, as AIST++ mostly has."""
    return f"setting{genre_index + 1}"


def synth_camera_setting(seed: int) -> list[dict[str, Any]]:
    """Nine cameras (c01…c09) as AIST++ JSON entries, reproducible from ``seed``."""
    rng = np.random.default_rng(seed)
    cameras = []
    for i in range(N_CAMERAS):
        azimuth = 2 * np.pi * i / N_CAMERAS + rng.uniform(-0.1, 0.1)
        radius, height = rng.uniform(430.0, 500.0), rng.uniform(150.0, 200.0)
        centre = np.array([radius * np.sin(azimuth), height, radius * np.cos(azimuth)])
        target = FLOOR_TARGET_CM + rng.uniform(-15.0, 15.0, 3)
        rotation = look_at(centre, target)
        focal = rng.uniform(1300.0, 1650.0)
        width, height_px = IMAGE_SIZE
        cameras.append(
            {
                "name": f"c{i + 1:02d}",
                "size": [width, height_px],
                "matrix": [[focal, 0.0, width / 2], [0.0, focal, height_px / 2], [0.0, 0.0, 1.0]],
                "distortions": [float(rng.uniform(-0.12, 0.07)), 0.0, 0.0, 0.0, 0.0],
                "rotation": Rotation.from_matrix(rotation).as_rotvec().tolist(),
                "translation": (-rotation @ centre).tolist(),
            }
        )
    return cameras


def camera_arrays(cameras: list[dict[str, Any]]) -> dict[str, np.ndarray]:
    """Stacked parameters of AIST++ JSON cameras: intrinsics (C, 3, 3), rvec (C, 3),
    translation (C, 3) in the file's unit (cm), distortions (C, 5)."""
    return {
        "intrinsics": np.array([c["matrix"] for c in cameras], dtype=np.float64),
        "rvec": np.array([c["rotation"] for c in cameras], dtype=np.float64),
        "translation": np.array([c["translation"] for c in cameras], dtype=np.float64),
        "distortions": np.array([c["distortions"] for c in cameras], dtype=np.float64),
    }
