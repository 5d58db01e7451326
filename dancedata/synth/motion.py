"""Synthetic SMPL dance motion: stepping feet, beat-locked accents, genre-dependent energy.

Pure functions. :mod:`dancedata.synth.choreography` plans one key pose per beat (feet, body
level, arm poses); here the keys become frames. Pose changes arrive *on* the beats of the
synthetic music (:mod:`dancedata.synth.music`: beats at b · 60 / bpm s from t = 0, kick and
snare on every beat, a pickup kick on the "and" of beat 4 in odd measures), with a sharp stop on
arrival, a pelvis dip and a head/shoulder accent at each onset. Feet are planted (zero speed, on
the floor) except while they step, and the root follows the feet: the pelvis sits between them
and shifts onto the standing foot. The legs are solved by two-bone inverse kinematics on
:data:`dancedata.compute.smpl.SMPL_REST_OFFSETS_M` so the planted ankles stay put; ankles, feet,
wrists and hands barely rotate, as in AIST++'s fits. Angles radians, lengths metres, y up,
floor y = 0.
How the ranges were calibrated on real AIST++ motion: docs/STORE.md, "The synthetic twin's
motion".
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.spatial.transform import Rotation

from dancedata.compute.camera import rodrigues_to_rotmat
from dancedata.compute.smpl import SMPL_PARENTS, SMPL_REST_OFFSETS_M
from dancedata.synth.choreography import beat_position, hit_curve, plan_beats
from dancedata.synth.styles import style_of


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


# Skeleton the legs are solved on (the synthetic keypoints are drawn from the same one).
_HIP_OFFSETS = SMPL_REST_OFFSETS_M[[1, 2]]  # left, right hip from the pelvis
_THIGH = SMPL_REST_OFFSETS_M[[4, 5]]  # knee from hip
_SHIN = SMPL_REST_OFFSETS_M[[7, 8]]  # ankle from knee
_LEG_M = float(np.linalg.norm(_THIGH[0]) + np.linalg.norm(_SHIN[0]))
ANKLE_HEIGHT_M = 0.075  # ankle joint above the floor when the foot is planted
MAX_REACH = 0.985  # hip-to-ankle distance at most this fraction of the leg (knees never lock)
STAND_PELVIS_M = ANKLE_HEIGHT_M + 0.965 * _LEG_M - _HIP_OFFSETS[0, 1]
ACCENT_PEAK_S = 0.06  # head and shoulder accents peak this long after their onset
KICK_LIFT_M, KICK_REACH_M = 0.42, 0.30
SPIN_LIFT_M = 0.10
SPIN_BEATS = 0.8  # a floor spin turns once in the last 0.8 beat before its beat
# Joints AIST++'s fits hardly rotate (mean |rotation| about 0.5–1.5°): ankles, feet, wrists, hands.
_STILL_JOINTS = (7, 8, 10, 11, 20, 21, 22, 23)


@dataclass(frozen=True)
class SynthDance:
    """One synthetic dance: what the motion file holds plus the plan behind it."""

    poses: np.ndarray  # (F, 72) float32 axis-angle, radians
    trans: np.ndarray  # (F, 3) float32 root position, metres, y up, floor at y = 0
    contact: np.ndarray  # (F, 2) bool: left / right ankle planted on its ground point
    ankle_target: np.ndarray  # (F, 2, 3) where the legs' IK put the ankles
    beat_position: np.ndarray  # (F,) time in beats (beat b at b · 60 / bpm s)
    accent: np.ndarray  # (F,) the onset accent envelope driving the head and shoulders


def _rot_y(a: np.ndarray) -> np.ndarray:
    c, s, z, o = np.cos(a), np.sin(a), np.zeros_like(a), np.ones_like(a)
    return np.stack(
        [np.stack([c, z, s], -1), np.stack([z, o, z], -1), np.stack([-s, z, c], -1)], -2
    )


def _rot_x(a: np.ndarray) -> np.ndarray:
    c, s, z, o = np.cos(a), np.sin(a), np.zeros_like(a), np.ones_like(a)
    return np.stack(
        [np.stack([o, z, z], -1), np.stack([z, c, -s], -1), np.stack([z, s, c], -1)], -2
    )


def _rot_z(a: np.ndarray) -> np.ndarray:
    c, s, z, o = np.cos(a), np.sin(a), np.zeros_like(a), np.ones_like(a)
    return np.stack(
        [np.stack([c, -s, z], -1), np.stack([s, c, z], -1), np.stack([z, z, o], -1)], -2
    )


def _unit(v: np.ndarray) -> np.ndarray:
    return v / np.maximum(np.linalg.norm(v, axis=-1, keepdims=True), 1e-12)


def _frame(direction: np.ndarray, hinge: np.ndarray) -> np.ndarray:
    """(..., 3, 3) orthonormal frame with columns [d, h⊥, d × h⊥]."""
    d = _unit(direction)
    h = _unit(hinge - np.sum(hinge * d, axis=-1, keepdims=True) * d)
    return np.stack([d, h, np.cross(d, h)], axis=-1)


def leg_ik(
    hip: np.ndarray, ankle: np.ndarray, forward: np.ndarray, thigh: np.ndarray, shin: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """Two-bone IK: world rotations (F, 3, 3) of the thigh and the shin that put the ankle at
    ``ankle`` from ``hip`` (F, 3), the knee bending towards ``forward`` (F, 3), for rest bones
    ``thigh`` and ``shin`` (3,). The knee is a hinge about the leg plane's normal; a target out
    of reach gets the straight leg pointing at it."""
    l1, l2 = float(np.linalg.norm(thigh)), float(np.linalg.norm(shin))
    d = ankle - hip
    dist = np.clip(np.linalg.norm(d, axis=-1), abs(l1 - l2) + 1e-6, l1 + l2 - 1e-9)
    u = _unit(d)
    w = _unit(forward - np.sum(forward * u, axis=-1, keepdims=True) * u)
    cos_b = np.clip((l1 * l1 + dist * dist - l2 * l2) / (2 * l1 * dist), -1.0, 1.0)
    knee = hip + l1 * (cos_b[:, None] * u + np.sqrt(1 - cos_b * cos_b)[:, None] * w)
    hinge = np.cross(w, u)  # +x for a straight leg down with the knee forward
    x = np.array([1.0, 0.0, 0.0])
    rest_thigh, rest_shin = _frame(thigh, x), _frame(shin, x)
    w_thigh = _frame(knee - hip, hinge) @ rest_thigh.T
    w_shin = _frame(ankle - knee, hinge) @ rest_shin.T
    return w_thigh, w_shin


def _smooth(x: np.ndarray, sigma_frames: float) -> np.ndarray:
    from scipy.ndimage import gaussian_filter1d

    return gaussian_filter1d(x, sigma_frames, axis=0, mode="nearest")


def _onset_accent(t: np.ndarray, bpm: float, strengths: np.ndarray) -> np.ndarray:
    """(F,) Σ over onsets of strength · x² e^(2(1 − x)), x = (t − onset) / τ after each onset:
    a pulse that leaves rest on the onset (a jolt of acceleration there), peaks τ later and
    fades. Onsets: every beat (its plan's accent) and the music's pickup kick on the "and" of
    beat 4 of odd measures."""
    beat_s = 60.0 / bpm
    onsets = [(b * beat_s, float(a)) for b, a in enumerate(strengths)]
    onsets += [((4 * m + 3.5) * beat_s, 0.5) for m in range(1, len(strengths) // 4 + 1, 2)]
    env = np.zeros_like(t)
    for when, strength in onsets:
        after = t >= when
        x = (t[after] - when) / ACCENT_PEAK_S
        env[after] += strength * x * x * np.exp(2.0 * (1.0 - x))
    return env


def synth_dance(
    n_frames: int,
    fps: float,
    bpm: float,
    seed: int = 0,
    genre: str | None = None,
    situation: str = "sBM",
) -> SynthDance:
    """A dance of ``n_frames`` at ``fps`` to music at ``bpm`` in the style of ``genre`` (an
    AIST++ genre code; see :mod:`dancedata.synth.styles`), basic (``sBM``) or advanced."""
    rng = np.random.default_rng(seed)
    base = style_of(genre)
    vigour = rng.uniform(0.85, 1.15)  # this dancer's energy
    attack = float(np.clip(base.attack * rng.uniform(0.85, 1.15), 0.15, 0.9))
    sharp = float(np.clip(base.sharp + rng.normal(0, 0.05), 0.0, 1.0))
    t = np.arange(n_frames) / fps
    beat_pos = beat_position(n_frames, fps, bpm)
    n_beats = int(np.floor(beat_pos[-1])) + 2
    plan = plan_beats(n_beats, base, rng, situation)

    # Facing, body level and pitch: keys reached on the beats.
    # Pose changes take the whole beat and come to rest on it (the motion's speed minima, its
    # "motion beats", fall on the music's beats); ``attack`` sets how fast a step's swing is.
    steps_heading = hit_curve(plan.heading, beat_pos, 1.0, sharp)
    spin_angle = hit_curve(plan.spin_turn, beat_pos, SPIN_BEATS, 0.0)
    heading = steps_heading + spin_angle
    drop = hit_curve(plan.drop, beat_pos, max(attack, 0.5), 0.3)
    pitch = hit_curve(plan.pitch, beat_pos, max(attack, 0.5), 0.3)
    b = np.floor(beat_pos).astype(np.int64)  # the beat before each frame
    nxt = np.minimum(b + 1, n_beats - 1)  # the beat each frame is moving towards
    swing_attack = max(attack, 0.5)  # a step takes at least half a beat
    swing_v = np.clip((beat_pos - b - (1 - swing_attack)) / swing_attack, 0.0, 1.0)

    # Feet: planted on their ground point, or swinging to the next one (lifted mid-swing).
    ground = np.stack([hit_curve(plan.feet[:, k], beat_pos, swing_attack, 0.5 * sharp)
                       for k in (0, 1)], axis=1)  # fmt: skip
    ankle = np.concatenate([ground[..., :1], np.zeros((n_frames, 2, 1)), ground[..., 1:]], -1)
    ankle[..., 1] = ANKLE_HEIGHT_M
    contact = np.ones((n_frames, 2), dtype=bool)
    forward = np.stack([np.sin(heading), np.zeros(n_frames), np.cos(heading)], axis=-1)
    bump = np.sin(np.pi * swing_v)
    for k in (0, 1):
        swinging = (plan.step_foot[nxt] == k) & (swing_v > 0) & (swing_v < 1)
        contact[swinging, k] = False
        kick = swinging & plan.kick[nxt]
        lift = np.where(kick, KICK_LIFT_M * vigour, plan.step_height[nxt]) * bump
        ankle[swinging, k, 1] += lift[swinging]
        ankle[kick, k] += (KICK_REACH_M * bump[kick])[:, None] * forward[kick]
    spinning = plan.spin[nxt] & (beat_pos - b > 1 - SPIN_BEATS)
    if spinning.any():
        turn = spin_angle - plan.spin_turn[b]  # 0 → ±2π over the spin
        centre = np.concatenate([plan.centre[b][:, :1], np.zeros((n_frames, 1)),
                                 plan.centre[b][:, 1:]], -1)  # fmt: skip
        for k in (0, 1):
            rel = plan.feet[b, k] - plan.centre[b]
            rel3 = np.stack([rel[:, 0], np.zeros(n_frames), rel[:, 1]], -1)
            spun = centre + np.einsum("fij,fj->fi", _rot_y(turn), rel3)
            spun[:, 1] = (
                ANKLE_HEIGHT_M
                + SPIN_LIFT_M * np.sin(np.pi * np.clip(turn / (2 * np.pi), -1, 1)) ** 2
            )
            ankle[spinning, k] = spun[spinning]
            contact[spinning, k] = False

    # Pelvis: between the feet, shifted onto the standing foot, dipping on every beat.
    mid = ankle[..., [0, 2]].mean(axis=1)
    only_left = (contact[:, 0] & ~contact[:, 1])[:, None]
    only_right = (contact[:, 1] & ~contact[:, 0])[:, None]
    stance = np.where(
        only_left, ankle[:, 0, [0, 2]], np.where(only_right, ankle[:, 1, [0, 2]], mid)
    )
    shift = _smooth(0.45 * (stance - mid), 0.06 * fps)
    back = (
        0.12 * np.sin(pitch)[:, None] * np.stack([np.sin(steps_heading), np.cos(steps_heading)], -1)
    )  # sit back to balance a lean
    nearest = np.abs(beat_pos - np.round(beat_pos))
    bounce = base.bounce_m * vigour * np.exp(-0.5 * (nearest / 0.12) ** 2)
    pelvis = np.zeros((n_frames, 3))
    pelvis[:, [0, 2]] = mid + shift - back
    pelvis[:, 1] = STAND_PELVIS_M - drop - bounce
    roll = np.clip(
        np.einsum("fi,fi->f", shift, np.stack([np.cos(heading), -np.sin(heading)], -1)), -0.1, 0.1
    )
    twist = 0.08 * base.energy * np.sin(np.pi * beat_pos / 2 + rng.uniform(0, 2 * np.pi))
    r_pelvis = _rot_y(heading + twist) @ _rot_x(pitch) @ _rot_z(-1.2 * roll)
    # Lower the pelvis where a leg cannot reach its ankle target: the highest hip that keeps
    # the hip-to-ankle distance within MAX_REACH of the leg, at the same horizontal offset.
    hips = pelvis[:, None] + np.einsum("fij,kj->fki", r_pelvis, _HIP_OFFSETS)
    across = np.linalg.norm((ankle - hips)[..., [0, 2]], axis=-1)
    highest = ankle[..., 1] + np.sqrt(np.maximum((MAX_REACH * _LEG_M) ** 2 - across**2, 0.0))
    pelvis[:, 1] -= np.maximum(hips[..., 1] - highest, 0.0).max(axis=1)
    hips = pelvis[:, None] + np.einsum("fij,kj->fki", r_pelvis, _HIP_OFFSETS)

    rot = np.zeros((n_frames, 24, 3, 3))
    rot[:, 0] = r_pelvis
    for k, (hip_j, knee_j) in enumerate(((1, 4), (2, 5))):
        w_thigh, w_shin = leg_ik(hips[:, k], ankle[:, k], forward, _THIGH[k], _SHIN[k])
        rot[:, hip_j] = np.swapaxes(r_pelvis, -1, -2) @ w_thigh
        rot[:, knee_j] = np.swapaxes(w_thigh, -1, -2) @ w_shin

    # Upper body: extrinsic x-y-z Euler angles per joint (x flexion, y twist, z side/abduction).
    accent = _onset_accent(t, bpm, plan.accent * vigour)
    euler = np.zeros((n_frames, 24, 3))
    torso = hit_curve(plan.torso, beat_pos, 1.0, sharp) * vigour
    for joint, share in ((3, 0.4), (6, 0.3), (9, 0.3)):
        euler[:, joint] = share * torso
    euler[:, 9, 0] += 0.05 * accent  # the chest hits the accent
    euler[:, 12, 0] = -0.4 * pitch + 0.08 * accent  # neck and head look up in floor work
    euler[:, 15, 0] = -0.3 * pitch + 0.2 * accent
    euler[:, 12, 1] = 0.4 * torso[:, 1]  # neck and head turn with the chest
    euler[:, 15, 1] = 0.9 * torso[:, 1]
    arms = hit_curve(plan.arms, beat_pos, 1.0, sharp)  # (F, 2, 4)
    shrug = 0.35 * (arms[:, :, 0] + 1.3)  # collars lift and swing with the arms
    euler[:, 13, 2] = 0.15 * accent + shrug[:, 0]
    euler[:, 14, 2] = -0.15 * accent - shrug[:, 1]
    euler[:, 13, 1] = 0.45 * arms[:, 0, 1]
    euler[:, 14, 1] = -0.45 * arms[:, 1, 1]
    swing = (
        0.18
        * base.energy
        * vigour
        * hit_curve(np.where(np.arange(n_beats) % 2 == 0, 1.0, -1.0), beat_pos, 1.0, sharp)
    )
    for k, (shoulder, elbow, sign) in enumerate(((16, 18, 1.0), (17, 19, -1.0))):
        gamma, beta, roll_arm, flex = (arms[:, k, i] for i in range(4))
        euler[:, shoulder] = np.stack(
            [roll_arm, sign * (beta + sign * swing), sign * gamma], axis=-1
        )
        euler[:, elbow, 1] = -sign * flex
    # Slow, small wandering of every joint, so that no pose ever freezes exactly.
    freq = rng.uniform(0.15, 0.6, (24, 3))
    phase = rng.uniform(0, 2 * np.pi, (24, 3))
    amp = np.full((24, 3), 0.03)
    amp[list(_STILL_JOINTS)] = 0.004
    euler += amp * np.sin(2 * np.pi * freq * t[:, None, None] + phase)
    euler[:, list(_STILL_JOINTS)] += rng.normal(0, 0.01, (len(_STILL_JOINTS), 3))

    poses = extrinsic_xyz_to_rotvec(euler)
    solved = [0, 1, 2, 4, 5]
    poses[:, solved] = (
        Rotation.from_matrix(rot[:, solved].reshape(-1, 3, 3))
        .as_rotvec()
        .reshape(n_frames, len(solved), 3)
    )
    return SynthDance(
        poses.reshape(n_frames, 72).astype(np.float32),
        pelvis.astype(np.float32),
        contact,
        ankle,
        beat_pos,
        accent,
    )


def synth_smpl_motion(
    n_frames: int,
    fps: float,
    bpm: float,
    seed: int = 0,
    genre: str | None = None,
    situation: str = "sBM",
) -> tuple[np.ndarray, np.ndarray]:
    """(smpl_poses (F, 72) axis-angle radians, root translation (F, 3) metres, y up) of
    :func:`synth_dance`."""
    dance = synth_dance(n_frames, fps, bpm, seed, genre, situation)
    return dance.poses, dance.trans


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
