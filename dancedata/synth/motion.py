"""Synthetic SMPL dance motion that moves in time with the music's beats and measures.

Pure functions. Joint angles are sums of sinusoids locked to the beat (period 60 / bpm seconds)
and the measure (4 beats), with amplitudes inside a comfortable range of motion, so that motion
beats, velocities and per-measure segments mean something. Angles are radians, lengths metres.
"""

from __future__ import annotations

import numpy as np
from scipy.spatial.transform import Rotation

from dancedata.compute.camera import rodrigues_to_rotmat
from dancedata.smpl import SMPL_PARENTS, SMPL_REST_OFFSETS_M

# Per joint: (axis, rest angle, beat amplitude, measure amplitude) in radians; axes are the
# joint's local x (flexion), y (twist) and z (abduction). Unlisted joints only sway slightly.
_JOINT_PATTERNS: dict[int, list[tuple[int, float, float, float]]] = {
    0: [(1, 0.0, 0.10, 0.6)],  # pelvis yaw: turns over each measure
    1: [(0, -0.25, 0.35, 0.15), (2, 0.08, 0.05, 0.05)],  # hips flex
    2: [(0, -0.25, 0.35, 0.15), (2, -0.08, 0.05, 0.05)],
    4: [(0, 0.45, 0.40, 0.10)],  # knees bend on the beat
    5: [(0, 0.45, 0.40, 0.10)],
    3: [(0, 0.05, 0.06, 0.04)],
    6: [(0, 0.03, 0.05, 0.03)],
    9: [(2, 0.0, 0.05, 0.08)],
    12: [(0, 0.05, 0.08, 0.05)],
    15: [(0, 0.0, 0.12, 0.05), (1, 0.0, 0.05, 0.15)],  # head nods on the beat
    16: [(2, -0.9, 0.45, 0.30), (1, 0.0, 0.20, 0.20)],  # shoulders swing the arms
    17: [(2, 0.9, 0.45, 0.30), (1, 0.0, 0.20, 0.20)],
    18: [(1, -0.6, 0.50, 0.20)],  # elbows
    19: [(1, 0.6, 0.50, 0.20)],
    7: [(0, -0.1, 0.12, 0.05)],
    8: [(0, -0.1, 0.12, 0.05)],
}


def extrinsic_xyz_to_rotvec(euler: np.ndarray) -> np.ndarray:
    """(..., 3) extrinsic x-y-z Euler angles (radians; scipy ``"xyz"``: R = Rz Ry Rx) → (..., 3)
    rotation vectors with angle in [0, π], as scipy's ``as_rotvec`` gives them. Closed form
    through the quaternion qz ⊗ qy ⊗ qx, vectorised (scipy loops per rotation)."""
    half = 0.5 * np.asarray(euler, dtype=np.float64)
    c, s = np.cos(half), np.sin(half)
    cx, cy, cz = c[..., 0], c[..., 1], c[..., 2]
    sx, sy, sz = s[..., 0], s[..., 1], s[..., 2]
    w = cz * cy * cx + sz * sy * sx
    v = np.stack(
        [
            cz * cy * sx - sz * sy * cx,
            cz * sy * cx + sz * cy * sx,
            sz * cy * cx - cz * sy * sx,
        ],
        axis=-1,
    )
    sign = np.where(w < 0, -1.0, 1.0)
    w, v = w * sign, v * sign[..., None]
    norm = np.linalg.norm(v, axis=-1)
    angle = 2.0 * np.arctan2(norm, w)
    scale = np.where(norm > 1e-12, angle / np.maximum(norm, 1e-300), 2.0 / np.maximum(w, 1e-300))
    return v * scale[..., None]


def synth_smpl_motion(
    n_frames: int, fps: float, bpm: float, seed: int = 0
) -> tuple[np.ndarray, np.ndarray]:
    """Return (smpl_poses (F, 72) axis-angle radians, root translation (F, 3) metres, y up).

    The dancer bobs down on every beat, turns back and forth once per measure and walks a
    slow circle of about 0.6 m radius; limbs swing with beat-locked phases per ``seed``.
    """
    rng = np.random.default_rng(seed)
    t = np.arange(n_frames) / fps
    beat_phase = 2 * np.pi * t * bpm / 60.0
    measure_phase = beat_phase / 4.0
    sway_phases = rng.uniform(0, 2 * np.pi, (24, 3))  # the same draws as joint by joint
    euler = 0.03 * np.sin(beat_phase[:, None, None] + sway_phases)
    for joint, patterns in _JOINT_PATTERNS.items():
        offset = rng.uniform(0, 2 * np.pi)
        for axis, rest, beat_amp, measure_amp in patterns:
            scale = rng.uniform(0.7, 1.2)
            euler[:, joint, axis] += (
                rest
                + scale * beat_amp * np.sin(beat_phase + offset)
                + scale * measure_amp * np.sin(measure_phase + offset / 2)
            )
    # Knees only bend one way.
    euler[:, 4, 0] = np.abs(euler[:, 4, 0])
    euler[:, 5, 0] = np.abs(euler[:, 5, 0])
    poses = extrinsic_xyz_to_rotvec(euler).reshape(n_frames, 72)
    radius = rng.uniform(0.4, 0.8)
    orbit = 2 * np.pi * t / (16 * 4 * 60.0 / bpm)  # one lap per 16 measures
    trans = np.stack(
        [
            radius * np.sin(orbit),
            0.92 - 0.04 * (1 + np.cos(beat_phase)) / 2,  # pelvis height dips on each beat
            radius * (1 - np.cos(orbit)),
        ],
        axis=1,
    )
    return poses.astype(np.float32), trans.astype(np.float32)


def smpl_joint_positions(poses: np.ndarray, trans: np.ndarray) -> np.ndarray:
    """World positions (F, 24, 3) in metres of the approximate rest skeleton posed by ``poses``
    (F, 72) and ``trans`` (F, 3); used to draw synthetic keypoints, not a SMPL model."""
    n_frames = poses.shape[0]
    local = rodrigues_to_rotmat(poses.reshape(n_frames, 24, 3))
    world_rot = np.empty_like(local)
    positions = np.empty((n_frames, 24, 3))
    for joint, parent in enumerate(SMPL_PARENTS):
        if parent < 0:
            world_rot[:, joint] = local[:, joint]
            positions[:, joint] = trans
        else:
            world_rot[:, joint] = world_rot[:, parent] @ local[:, joint]
            positions[:, joint] = (
                positions[:, parent] + world_rot[:, parent] @ SMPL_REST_OFFSETS_M[joint]
            )
    return positions


# COCO-17 keypoint i sits at SMPL joint _COCO_FROM_SMPL[i] plus a head-relative offset (metres).
_COCO_FROM_SMPL = (15, 15, 15, 15, 15, 16, 17, 18, 19, 20, 21, 1, 2, 4, 5, 7, 8)
_COCO_HEAD_OFFSETS = np.array(
    [
        [0, 0.02, 0.10],
        [0.03, 0.05, 0.08],
        [-0.03, 0.05, 0.08],
        [0.07, 0.03, 0.0],
        [-0.07, 0.03, 0.0],
    ]
)


def coco17_keypoints(positions: np.ndarray, poses: np.ndarray) -> np.ndarray:
    """COCO-17 keypoints (F, 17, 3) in metres from SMPL joint positions (F, 24, 3)."""
    keypoints = positions[:, list(_COCO_FROM_SMPL), :].copy()
    n_frames = positions.shape[0]
    head_rot = Rotation.from_rotvec(poses[:, :3].astype(np.float64))  # root orientation
    for i, offset in enumerate(_COCO_HEAD_OFFSETS):
        keypoints[:, i] += head_rot.apply(np.tile(offset, (n_frames, 1)))
    return keypoints
