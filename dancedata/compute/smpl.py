"""The SMPL 24-joint kinematic tree used by AIST++ motions, and COCO-17 keypoint names.

No SMPL model is bundled (its licence forbids redistribution). ``SMPL_REST_OFFSETS_M`` is a
rounded, hand-made approximation of a mean adult's rest skeleton (y-up, metres), good enough to
draw plausible synthetic keypoints; it is not a substitute for the model's joint regressor.
"""

from __future__ import annotations

import numpy as np

SMPL_JOINTS: tuple[str, ...] = (
    "pelvis",
    "left_hip",
    "right_hip",
    "spine1",
    "left_knee",
    "right_knee",
    "spine2",
    "left_ankle",
    "right_ankle",
    "spine3",
    "left_foot",
    "right_foot",
    "neck",
    "left_collar",
    "right_collar",
    "head",
    "left_shoulder",
    "right_shoulder",
    "left_elbow",
    "right_elbow",
    "left_wrist",
    "right_wrist",
    "left_hand",
    "right_hand",
)
SMPL_PARENTS: tuple[int, ...] = (
    -1,
    0,
    0,
    0,
    1,
    2,
    3,
    4,
    5,
    6,
    7,
    8,
    9,
    9,
    9,
    12,
    13,
    14,
    16,
    17,
    18,
    19,
    20,
    21,
)
# Offset of each joint from its parent in the rest pose (metres, y up, x to the body's left).
SMPL_REST_OFFSETS_M = np.array(
    [
        [0.0, 0.0, 0.0],
        [0.06, -0.09, 0.0],
        [-0.06, -0.09, 0.0],
        [0.0, 0.11, -0.02],
        [0.04, -0.38, 0.0],
        [-0.04, -0.38, 0.0],
        [0.0, 0.14, 0.01],
        [-0.01, -0.40, -0.04],
        [0.01, -0.40, -0.04],
        [0.0, 0.06, 0.0],
        [0.03, -0.06, 0.12],
        [-0.03, -0.06, 0.12],
        [0.0, 0.21, -0.03],
        [0.08, 0.12, -0.02],
        [-0.08, 0.12, -0.02],
        [0.0, 0.09, 0.05],
        [0.12, 0.04, -0.01],
        [-0.12, 0.04, -0.01],
        [0.26, -0.01, -0.02],
        [-0.26, -0.01, -0.02],
        [0.25, 0.01, 0.0],
        [-0.25, 0.01, 0.0],
        [0.08, -0.01, -0.01],
        [-0.08, -0.01, -0.01],
    ],
    dtype=np.float64,
)
COCO17_KEYPOINTS: tuple[str, ...] = (
    "nose",
    "left_eye",
    "right_eye",
    "left_ear",
    "right_ear",
    "left_shoulder",
    "right_shoulder",
    "left_elbow",
    "right_elbow",
    "left_wrist",
    "right_wrist",
    "left_hip",
    "right_hip",
    "left_knee",
    "right_knee",
    "left_ankle",
    "right_ankle",
)
COCO17_PARENTS: tuple[int, ...] = (-1, 0, 0, 1, 2, 0, 0, 5, 6, 7, 8, 5, 6, 11, 12, 13, 14)
