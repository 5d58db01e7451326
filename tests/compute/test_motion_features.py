"""Motion features: derivatives, angular velocity, motion beats and beat-alignment scores,
kinetic and geometric features, against formulas, hand-worked cases and plain-loop
re-computations of the reference algorithms."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy.spatial.transform import Rotation

from dancedata.compute.motion_features import (
    HUMERUS_M,
    SMPL_JOINT_NAMES,
    acceleration,
    angular_velocity,
    beat_align_score_bailando,
    beat_align_score_mint,
    geometric_feature_frames,
    geometric_features,
    jerk,
    kinetic_features,
    motion_beats_bailando,
    motion_beats_mint,
    velocity,
    weight_effort,
)

# --------------------------------------------------------------------------------------------
# Derivatives and angular velocity


def test_derivatives_of_a_cubic():
    fps = 50.0
    t = np.arange(20) / fps
    x = np.stack([t**3, 2 * t], axis=1)
    np.testing.assert_allclose(jerk(x, fps)[:, 0], 6.0, rtol=1e-6)
    np.testing.assert_allclose(velocity(x, fps)[:, 1], 2.0, rtol=1e-12)
    np.testing.assert_allclose(acceleration(x, fps)[:, 1], 0.0, atol=1e-9)
    np.testing.assert_allclose(acceleration(x, fps)[:, 0], 6 * (t[1:-1]), rtol=1e-6)
    assert velocity(x, fps).shape == (19, 2) and jerk(x, fps).shape == (17, 2)


def test_angular_velocity_of_a_constant_spin():
    fps, omega = 120.0, np.array([0.0, 2.0, -1.0])  # rad/s, in the parent frame
    t = np.arange(50) / fps
    base = Rotation.from_euler("xyz", [0.3, -0.2, 1.0])
    rots = Rotation.from_rotvec(t[:, None] * omega) * base
    quat = rots.as_quat()[:, [3, 0, 1, 2]]
    quat[::3] *= -1  # q and -q are the same rotation
    w = angular_velocity(quat[:, None], fps)[:, 0]
    np.testing.assert_allclose(w, np.broadcast_to(omega, w.shape), rtol=1e-4, atol=1e-4)
    # Against the exact per-step rotation vector from scipy.
    step = (rots[1:] * rots[:-1].inv()).as_rotvec() * fps
    np.testing.assert_allclose(w, step, atol=1e-4)


def test_weight_effort_sums_joint_speeds():
    rng = np.random.default_rng(0)
    rots = Rotation.from_rotvec(rng.normal(scale=0.05, size=(30 * 3, 3)).cumsum(axis=0))
    quat = rots.as_quat()[:, [3, 0, 1, 2]].reshape(30, 3, 4)
    w = angular_velocity(quat, 60.0)
    effort = weight_effort(quat, 60.0)
    assert effort.shape == (29,)
    np.testing.assert_allclose(effort, np.linalg.norm(w, axis=-1).sum(axis=1))


# --------------------------------------------------------------------------------------------
# Motion beats and beat alignment

MINIMA = (30, 90, 150)


def _motion_with_speed_minima(n_frames: int = 181, n_joints: int = 4) -> np.ndarray:
    """Joints move along x; the step arriving at frame t has length 1.1 − cos(2π(t−30)/60),
    whose minima are at frames 30, 90, 150."""
    t = np.arange(1, n_frames)
    steps = 1.1 - np.cos(2 * np.pi * (t - 30) / 60)
    x = np.concatenate([[0.0], np.cumsum(steps)])
    pos = np.zeros((n_frames, n_joints, 3))
    pos[:, :, 0] = x[:, None] * (1 + np.arange(n_joints))  # different speeds, same minima
    return pos


def test_motion_beats_mint_and_bailando_on_known_minima():
    pos = _motion_with_speed_minima()
    np.testing.assert_array_equal(motion_beats_mint(pos), MINIMA)
    # Bailando's envelope index t is the step from t to t+1: one frame earlier.
    np.testing.assert_array_equal(motion_beats_bailando(pos), np.array(MINIMA) - 1)


def test_mint_order_controls_the_neighbourhood():
    # A shallow dip at the speed maximum (frame 60) is a minimum over ±2 frames, not over ±10.
    pos = _motion_with_speed_minima()
    pos[60:, :, 0] -= 0.05 * (1 + np.arange(4))
    assert 60 not in motion_beats_mint(pos)
    assert 60 in motion_beats_mint(pos, order=2)


def _loop_score(points, targets, sigma):
    scores = []
    for p in points:
        d = min(abs(p - q) for q in targets)
        scores.append(np.exp(-(d**2) / (2 * sigma**2)))
    return sum(scores) / len(scores)


def test_beat_alignment_scores_hand_case():
    music, motion = np.array([0, 30, 60]), np.array([31, 58])
    mint = beat_align_score_mint(music, motion)
    bailando = beat_align_score_bailando(music, motion)
    assert mint == pytest.approx((np.exp(-1 / 18) + np.exp(-4 / 18)) / 2)
    assert bailando == pytest.approx(
        (np.exp(-(31**2) / 18) + np.exp(-1 / 18) + np.exp(-4 / 18)) / 3
    )
    assert mint != pytest.approx(bailando)
    # Bailando keeps only music beats inside the envelope length.
    assert beat_align_score_bailando(music, motion, n_frames=60) == pytest.approx(
        (np.exp(-(31**2) / 18) + np.exp(-1 / 18)) / 2
    )
    assert beat_align_score_mint(music, []) == 0.0
    assert beat_align_score_bailando(music, []) == 0.0
    assert np.isnan(beat_align_score_bailando([], motion))


@settings(max_examples=40, deadline=None)
@given(
    st.lists(st.integers(0, 500), min_size=1, max_size=20),
    st.lists(st.integers(0, 500), min_size=1, max_size=20),
)
def test_beat_alignment_scores_equal_plain_loops(music, motion):
    assert beat_align_score_mint(music, motion) == pytest.approx(_loop_score(motion, music, 3))
    assert beat_align_score_bailando(music, motion) == pytest.approx(_loop_score(music, motion, 3))


# --------------------------------------------------------------------------------------------
# Kinetic features


def _loop_kinetic(pos: np.ndarray, fps: float, parity: bool, window: int = 2) -> np.ndarray:
    """Straightforward per-frame, per-joint loops of the AIST++ kinetic feature definition."""
    dt = 1.0 / fps
    n, joints = pos.shape[:2]
    out = []
    for j in range(joints):
        h = v = e = 0.0
        for i in range(1, n):
            vel, count = np.zeros(3), 0
            for k in range(i - window, i + window + 1):
                if k - 1 >= 0 and k < n:
                    vel += pos[k, j] - pos[k - 1, j]
                    count += 1
            vel /= count * dt
            h += vel[0] ** 2 + vel[2] ** 2
            v += vel[1] ** 2
            acc, count = np.zeros(3), 0
            for k in range(i - window, i + window + 1):
                if k - 1 >= 0 and k + 1 < n:
                    v2 = (pos[k + 1, j] - pos[k, j]) / dt
                    v1 = (
                        pos[k, j] - pos[k - 1, j] / dt
                        if parity
                        else (pos[k, j] - pos[k - 1, j]) / dt
                    )
                    acc += (v2 - v1) / dt
                    count += 1
            e += np.linalg.norm(acc / count)
        out += [h / (n - 1), v / (n - 1), e / (n - 1)]
    return np.array(out)


@pytest.mark.parametrize("mode", ["parity", "corrected"])
def test_kinetic_features_equal_plain_loops(mode):
    pos = np.random.default_rng(5).normal(size=(17, 3, 3)).cumsum(axis=0) * 0.05
    got = kinetic_features(pos, 60.0, mode=mode)
    np.testing.assert_allclose(got, _loop_kinetic(pos, 60.0, mode == "parity"), rtol=1e-10)


def test_kinetic_features_hand_case():
    fps = 60.0
    pos = np.zeros((30, 24, 3))
    pos[:, 0] = np.arange(30)[:, None] / fps * np.array([1.0, 2.0, 0.0])  # 1 m/s x, 2 m/s up
    pos[:, 1] = [0.1, 0.0, 0.0]  # still, 10 cm off the origin
    corrected = kinetic_features(pos, fps, mode="corrected")
    parity = kinetic_features(pos, fps, mode="parity")
    assert corrected.shape == parity.shape == (72,)
    np.testing.assert_allclose(corrected[0:3], [1.0, 4.0, 0.0], atol=1e-9)
    np.testing.assert_allclose(corrected[3:6], [0.0, 0.0, 0.0], atol=1e-12)
    # Parity: v1 = p − p_prev / dt, so a still joint at c "accelerates" by |c|·(fps − 1)·fps.
    np.testing.assert_allclose(parity[3:6], [0.0, 0.0, 0.1 * 59 * 60], rtol=1e-12)
    np.testing.assert_allclose(parity[:2], corrected[:2])
    z_up = kinetic_features(pos[..., [0, 2, 1]], fps, mode="corrected", up_axis="z")
    np.testing.assert_allclose(z_up, corrected, atol=1e-9)


# --------------------------------------------------------------------------------------------
# Geometric features

T_POSE = np.array(
    [
        [0, 0.9, 0], [0.06, 0.82, 0], [-0.06, 0.82, 0], [0, 1.0, 0], [0.1, 0.45, 0],
        [-0.1, 0.45, 0], [0, 1.1, 0], [0.1, 0.05, 0], [-0.1, 0.05, 0], [0, 1.3, 0],
        [0.1, 0.0, 0.1], [-0.1, 0.0, 0.1], [0, 1.5, 0], [0.08, 1.45, 0], [-0.08, 1.45, 0],
        [0, 1.6, 0.05], [0.18, 1.42, 0], [-0.18, 1.42, 0], [0.44, 1.42, 0], [-0.44, 1.42, 0],
        [0.68, 1.42, 0], [-0.68, 1.42, 0], [0.76, 1.42, 0], [-0.76, 1.42, 0],
    ]
)  # fmt: skip
J = {n: i for i, n in enumerate(SMPL_JOINT_NAMES)}


def _clip(*poses: np.ndarray) -> np.ndarray:
    return np.stack(poses)


def test_geometric_features_hand_case_t_pose():
    feats = geometric_features(_clip(T_POSE, T_POSE))
    assert feats.shape == (32,)
    # 8: hands more than 2.5 shoulder widths apart along the shoulder line; 23, 24: upper arms
    # at 90° to the neck→root line (inside 25°-180°); 15: the left ankle lies 0.125 m in front
    # of the plane (root, rhip, rtoes), more than 0.38 humerus (its mirror 14 is behind).
    # Off: straight elbows and knees (6, 7, 19, 20), upright trunk (28), feet on the floor
    # (16, 17), hands high (29, 30), and every velocity predicate.
    assert set(np.flatnonzero(feats)) == {8, 15, 23, 24}

    bent = T_POSE.copy()
    bent[J["rwrist"]] = bent[J["relbow"]] + [0, 0.24, 0]  # right elbow at 90°
    bent[J["rankle"]] = [-0.1, 0.5, 0]  # right foot raised 0.45 m above the lowest joint
    bent[J["lwrist"]] = [0.3, 0.1, 0]  # left hand near the floor
    on = set(np.flatnonzero(geometric_features(_clip(bent, bent))))
    assert {6, 16, 30} <= on  # elbow angle, foot raised, left hand low
    assert not ({12, 13, 21, 22, 31} & on)  # nothing moves


def test_velocity_predicates_use_the_frame_time():
    moved = T_POSE.copy()
    moved[:, 0] += 0.004  # whole body 4 mm sideways in one frame
    # 0.004 m per 1/120 s = 0.48 m/s < 2.3 humerus/s = 0.59 m/s: root not "fast".
    frames = geometric_feature_frames(_clip(T_POSE, moved))
    assert not frames[0, 31]
    moved[:, 0] += 0.002  # 6 mm per frame = 0.72 m/s
    assert geometric_feature_frames(_clip(T_POSE, moved))[0, 31]
    assert 0.006 * 120 > 2.3 * HUMERUS_M > 0.004 * 120
    # Physical 60 fps timing halves the speed: not fast any more.
    assert not geometric_feature_frames(_clip(T_POSE, moved), frame_time_s=1 / 60)[0, 31]


@settings(max_examples=20, deadline=None)
@given(st.integers(0, 10_000), st.floats(-np.pi, np.pi), st.floats(-5, 5), st.floats(-5, 5))
def test_geometric_features_invariant_to_floor_translation_and_yaw(seed, yaw, dx, dz):
    rng = np.random.default_rng(seed)
    clip = T_POSE + rng.normal(scale=0.05, size=(6, 24, 3))
    clip[:, :, 1] += rng.normal(scale=0.02, size=(6, 1))
    rot = Rotation.from_euler("y", yaw).as_matrix()
    moved = clip @ rot.T + np.array([dx, 0.3, dz])
    a = geometric_feature_frames(clip)
    b = geometric_feature_frames(moved)
    assert a.shape == (5, 32)
    # Predicates sit on thresholds only by accident; allow no disagreement.
    np.testing.assert_array_equal(a, b)


def test_feature_input_validation():
    with pytest.raises(ValueError):
        kinetic_features(np.zeros((2, 24, 3)), 60.0, mode="parity")
    with pytest.raises(ValueError):
        kinetic_features(np.zeros((5, 24, 3)), 60.0, mode="exact")  # type: ignore[arg-type]
    with pytest.raises(ValueError):
        geometric_features(np.zeros((5, 17, 3)))
