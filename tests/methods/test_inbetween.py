"""In-betweening (docs/EXPERIMENTS.md §3, tests of §7.1) and the real-data anchor of §7.2.

References: scipy ``Rotation``/``Slerp`` for rotations, ``np.interp`` for translation,
``np.linalg.lstsq`` and ``scipy.optimize.least_squares(method="lm")`` for the Bézier fit, and
the spec's own MSE figures on the four real AIST++ motions.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from scipy.spatial.transform import Rotation, Slerp

from dancedata.errors import InputError
from dancedata.methods.bezier import (
    BezierTrainMean,
    bernstein3,
    bezier_eval,
    bezier_fit,
    bezier_reconstruction,
    linear_channels,
)
from dancedata.methods.inbetween import linear_slerp, segment_map
from dancedata.methods.keyframes import even_indices
from dancedata.metrics.reconstruction_error import mse_euler75


def wxyz(rotation: Rotation) -> np.ndarray:
    return rotation.as_quat()[..., [3, 0, 1, 2]]


# --------------------------------------------------------------------------- segment map


def test_segment_map_of_two_measures() -> None:
    seg = segment_map(np.array([100, 10]), np.array([5, 4]), np.array([[0, 2, 4], [0, 1, 3]]))
    assert seg.frame.tolist() == [100, 101, 102, 103, 104, 10, 11, 12, 13]
    assert seg.slot.tolist() == [0, 0, 1, 1, 1, 0, 1, 1, 1]
    assert seg.left.tolist() == [100, 100, 102, 102, 102, 10, 11, 11, 11]
    assert seg.right.tolist() == [102, 102, 104, 104, 104, 11, 13, 13, 13]
    np.testing.assert_allclose(seg.u, [0, 0.5, 0, 0.5, 1, 0, 0, 0.5, 1])
    assert seg.is_keyframe.tolist() == [1, 0, 1, 0, 1, 1, 1, 0, 1]
    assert seg.segment.tolist() == [0, 0, 1, 1, 1, 2, 3, 3, 3]
    a, b = seg.segment_ends()
    assert a.tolist() == [100, 102, 10, 11] and b.tolist() == [102, 104, 11, 13]


def test_segment_map_refuses_keyframes_that_miss_the_ends() -> None:
    with pytest.raises(InputError, match="strictly increasing"):
        segment_map(np.array([0]), np.array([5]), np.array([[0, 2, 3]]))
    with pytest.raises(InputError, match="strictly increasing"):
        segment_map(np.array([0]), np.array([5]), np.array([[0, 2, 2, 4]]))


# -------------------------------------------------------------------------- linear_slerp


def random_motion(frames: int, joints: int, seed: int) -> tuple[np.ndarray, np.ndarray]:
    rng = np.random.default_rng(seed)
    rotvec = rng.normal(scale=0.3, size=(frames, joints, 3)).cumsum(axis=0)
    return rotvec, rng.normal(size=(frames, 3)).cumsum(axis=0)


def test_midpoint_of_identity_and_a_quarter_turn_about_x() -> None:
    quat = wxyz(Rotation.from_euler("x", [[0.0], [0.0], [90.0]], degrees=True))[:, None]
    seg = segment_map(np.array([0]), np.array([3]), np.array([[0, 2]]))
    rec = linear_slerp(quat, np.zeros((3, 3)), seg)
    mid = Rotation.from_quat(rec.quat[1, 0, [1, 2, 3, 0]])
    assert (mid * Rotation.from_euler("x", 45, degrees=True).inv()).magnitude() < 1e-12


def test_slerp_takes_the_short_arc() -> None:
    # 0 and 300° about z: the short way passes −30°, not 150°; the sign of q_b must not matter
    q_end = wxyz(Rotation.from_euler("z", 300, degrees=True))
    for sign in (1.0, -1.0):
        identity = wxyz(Rotation.identity())
        quat = np.stack([identity, identity, sign * q_end])[:, None]  # frame 1 is in between
        seg = segment_map(np.array([0]), np.array([3]), np.array([[0, 2]]))
        rec = linear_slerp(quat, np.zeros((3, 3)), seg)
        mid = Rotation.from_quat(rec.quat[1, 0, [1, 2, 3, 0]])
        assert np.isclose(mid.as_euler("xyz", degrees=True)[2], -30.0, atol=1e-9)


def test_linear_slerp_equals_scipy_slerp_and_linear_translation() -> None:
    rotvec, trans = random_motion(60, 4, seed=0)
    quat = wxyz(Rotation.from_rotvec(rotvec.reshape(-1, 3))).reshape(60, 4, 4)
    starts, lengths = np.array([0, 25]), np.array([25, 35])
    keyframes = np.stack([even_indices(25, 5)[[0, 1, 2, 4]], even_indices(35, 4)])
    seg = segment_map(starts, lengths, keyframes)
    rec = linear_slerp(quat, trans, seg, "XYZ")
    for m in range(2):
        frames = np.arange(lengths[m])
        kf = keyframes[m]
        got = rec.quat[seg.measure == m]
        for j in range(4):
            ref = Slerp(kf, Rotation.from_rotvec(rotvec[starts[m] + kf, j]))(frames)
            diff = Rotation.from_quat(got[:, j, [1, 2, 3, 0]]) * ref.inv()
            assert diff.magnitude().max() < 1e-9
        for d in range(3):
            want = np.interp(frames, kf, trans[starts[m] + kf, d])
            np.testing.assert_allclose(rec.trans[seg.measure == m, d], want, atol=1e-12)


def test_keyframe_rows_are_exact_in_every_layout() -> None:
    rotvec, trans = random_motion(40, 24, seed=1)
    rotation = Rotation.from_rotvec(rotvec.reshape(-1, 3))
    quat = wxyz(rotation).reshape(40, 24, 4).astype(np.float32)
    euler = rotation.as_euler("XYZ").reshape(40, 24, 3).astype(np.float32)
    seg = segment_map(np.array([0]), np.array([40]), even_indices(40, 5)[None])
    rec = linear_slerp(quat, trans, seg, "XYZ", truth_euler=euler)
    keep = seg.is_keyframe
    truth75 = np.concatenate([trans, euler.reshape(40, -1)], axis=1)
    assert np.array_equal(rec.euler75()[keep], truth75[seg.frame[keep]])
    assert np.array_equal(rec.quat[keep], quat[seg.frame[keep]].astype(np.float64))
    # the layouts, against scipy
    out = Rotation.from_quat(rec.quat.reshape(-1, 4)[:, [1, 2, 3, 0]])
    r225 = rec.rotmat225()
    assert r225.shape == (40, 225) and (r225[:, :6] == 0).all()
    np.testing.assert_allclose(r225[:, 6:9], rec.trans)
    np.testing.assert_allclose(r225[:, 9:], out.as_matrix().reshape(40, 216), atol=1e-12)
    free = ~keep
    np.testing.assert_allclose(
        rec.euler75()[free, 3:], out.as_euler("XYZ").reshape(40, 72)[free], atol=1e-12
    )
    np.testing.assert_allclose(
        Rotation.from_rotvec(rec.axis_angle().reshape(-1, 3)).as_matrix(),
        out.as_matrix(),
        atol=1e-12,
    )


def test_many_measures_at_once_equal_one_at_a_time() -> None:
    rotvec, trans = random_motion(90, 3, seed=2)
    quat = wxyz(Rotation.from_rotvec(rotvec.reshape(-1, 3))).reshape(90, 3, 4)
    starts, lengths = np.array([0, 30, 62]), np.array([30, 32, 28])
    keyframes = np.stack([even_indices(int(length), 5) for length in lengths])
    together = linear_slerp(quat, trans, segment_map(starts, lengths, keyframes))
    for m in range(3):
        alone = linear_slerp(
            quat, trans, segment_map(starts[m : m + 1], lengths[m : m + 1], keyframes[m : m + 1])
        )
        np.testing.assert_array_equal(together.quat[together.segments.measure == m], alone.quat)


# ---------------------------------------------------------------------------------- Bézier


def bezier_data(
    gaps: list[int], channels: int, seed: int
) -> tuple[np.ndarray, np.ndarray, np.ndarray, object]:
    """One measure whose channels follow cubic Béziers with known P1, P2 between keyframes."""
    rng = np.random.default_rng(seed)
    keyframes = np.concatenate([[0], np.cumsum(gaps)])
    length = int(keyframes[-1]) + 1
    knots = rng.normal(size=(len(keyframes), channels))
    p1 = rng.normal(size=(len(gaps), channels))
    p2 = rng.normal(size=(len(gaps), channels))
    x = np.empty((length, channels))
    for s, (a, b) in enumerate(zip(keyframes[:-1], keyframes[1:], strict=True)):
        basis = bernstein3((np.arange(a, b + 1) - a) / (b - a))
        x[a : b + 1] = basis @ np.stack([knots[s], p1[s], p2[s], knots[s + 1]])
    seg = segment_map(np.array([0]), np.array([length]), keyframes[None])
    return x, p1, p2, seg


def test_bezier_fit_recovers_the_control_points() -> None:
    x, p1, p2, seg = bezier_data([12, 7, 20, 4], channels=6, seed=3)
    for solver in ("closed_form", "lm"):
        f1, f2 = bezier_fit(x, seg, solver)
        np.testing.assert_allclose(f1, p1, atol=1e-8)
        np.testing.assert_allclose(f2, p2, atol=1e-8)
    np.testing.assert_allclose(bezier_eval(x, seg, p1, p2), x, atol=1e-12)


def test_closed_form_and_lm_agree_on_motion_that_is_no_bezier() -> None:
    rng = np.random.default_rng(4)
    x = rng.normal(size=(75, 5)).cumsum(axis=0)
    seg = segment_map(np.array([0]), np.array([75]), even_indices(75, 6)[None])
    c1, c2 = bezier_fit(x, seg, "closed_form")
    l1, l2 = bezier_fit(x, seg, "lm")
    np.testing.assert_allclose(c1, l1, atol=1e-8)
    np.testing.assert_allclose(c2, l2, atol=1e-8)
    # and both are the lstsq solution of the spec, segment by segment
    a_all, b_all = seg.segment_ends()
    for s, (a, b) in enumerate(zip(a_all, b_all, strict=True)):
        basis = bernstein3((np.arange(a, b + 1) - a) / (b - a))
        target = x[a : b + 1] - np.outer(basis[:, 0], x[a]) - np.outer(basis[:, 3], x[b])
        want = np.linalg.lstsq(basis[:, 1:3], target, rcond=None)[0]
        np.testing.assert_allclose(c1[s], want[0], atol=1e-10)
        np.testing.assert_allclose(c2[s], want[1], atol=1e-10)


def test_short_segments_fall_back_to_the_chord() -> None:
    rng = np.random.default_rng(5)
    x = rng.normal(size=(10, 3))
    seg = segment_map(np.array([0]), np.array([10]), np.array([[0, 1, 3, 9]]))  # gaps 1, 2, 6
    for solver in ("closed_form", "lm"):
        p1, p2 = bezier_fit(x, seg, solver)
        for s, (a, b) in enumerate([(0, 1), (1, 3)]):
            np.testing.assert_allclose(p1[s], x[a] + (x[b] - x[a]) / 3, atol=1e-15)
            np.testing.assert_allclose(p2[s], x[a] + 2 * (x[b] - x[a]) / 3, atol=1e-15)
        curve = bezier_eval(x, seg, p1, p2)
        np.testing.assert_allclose(curve[2], (x[1] + x[3]) / 2, atol=1e-14)  # linear in u
        np.testing.assert_allclose(curve[:4], linear_channels(x, seg)[:4], atol=1e-14)


@pytest.mark.parametrize("param", ["absolute", "chord_relative"])
def test_train_mean_of_identical_measures_gives_their_control_points(param: str) -> None:
    x, p1, p2, one = bezier_data([10, 15, 9], channels=4, seed=6)
    length = x.shape[0]
    repeated = np.tile(x, (5, 1))
    keyframes = np.tile(np.array([[0, 10, 25, 34]]), (5, 1))
    train = segment_map(np.arange(5) * length, np.full(5, length), keyframes)
    model = BezierTrainMean(group="channel_slot", param=param).fit(repeated, train)
    q1, q2 = model.control_points(x, one)
    np.testing.assert_allclose(q1, p1, atol=1e-9)
    np.testing.assert_allclose(q2, p2, atol=1e-9)
    assert model.n_segments == 15
    with pytest.raises(InputError, match="N = 4"):
        model.control_points(x, segment_map(np.array([0]), np.array([length]), [[0, 20, 34]]))


def test_train_mean_by_channel_averages_over_slots() -> None:
    x, p1, p2, seg = bezier_data([10, 15, 9], channels=4, seed=7)
    model = BezierTrainMean(group="channel").fit(x, seg)
    q1, _ = model.control_points(x, seg)
    np.testing.assert_allclose(q1, np.broadcast_to(p1.mean(axis=0), q1.shape), atol=1e-9)


def test_bezier_reconstruction_layouts() -> None:
    rng = np.random.default_rng(8)
    x75 = np.concatenate([rng.normal(size=(30, 3)), rng.uniform(-1, 1, size=(30, 72))], axis=1)
    seg = segment_map(np.array([0]), np.array([30]), even_indices(30, 4)[None])
    p1, p2 = bezier_fit(x75, seg)
    rec = bezier_reconstruction(x75, seg, p1, p2, "XYZ")
    e75 = rec.euler75()
    assert np.array_equal(e75[seg.is_keyframe], x75[seg.frame[seg.is_keyframe]])
    np.testing.assert_allclose(e75, bezier_eval(x75, seg, p1, p2))
    want = Rotation.from_euler("XYZ", e75[:, 3:].reshape(-1, 3)).as_matrix().reshape(30, 216)
    np.testing.assert_allclose(rec.rotmat225()[:, 9:], want, atol=1e-12)
    linear_trans = bezier_reconstruction(x75, seg, p1, p2, "XYZ", trans_mode="linear")
    np.testing.assert_allclose(linear_trans.trans, linear_channels(x75, seg)[:, :3], atol=1e-12)


# ------------------------------------------------------------------------------------- MSE


def test_mse_euler75_convention() -> None:
    x = np.zeros((2, 75))
    assert mse_euler75(x, x) == 0.0
    y = x.copy()
    y[0, 0:3] = [1.0, 2.0, 2.0]  # translation error norm² 9
    y[1, 3] = 0.5  # one angle
    assert mse_euler75(x, y) == pytest.approx((9.0 + 0.25) / (2 * 25))
    z = x.copy()
    z[0, 10] = 2 * np.pi - 1e-3
    assert mse_euler75(x, z, wrap=True) == pytest.approx(1e-6 / 50)
    assert mse_euler75(x, z) == pytest.approx((2 * np.pi - 1e-3) ** 2 / 50)


# ----------------------------------------------------------------------- real data (§7.2)


@pytest.mark.real_data
def test_even_slerp_mse_on_the_real_aist_motions(real_data: Path) -> None:
    """even + linear_slerp, euler75, XYZ, raw angles, pooled over the 4 real sequences (27
    measures from the BPM of each music id): the spec's 0.336 / 0.209 / 0.084 within 1e-3."""
    from dancedata.compute.measures import measure_bounds
    from dancedata.compute.motion_representations import (
        continue_quat_signs,
        representations_from_axis_angle,
    )
    from dancedata.io.aist import read_motion
    from dancedata.io.aist_names import music_bpm, parse_sequence_name

    paths = sorted((real_data / "aist" / "motions").glob("*.pkl"))
    assert len(paths) == 4
    sequences = []
    for path in paths:
        motion = read_motion(path)
        reps = representations_from_axis_angle(motion.axis_angle, ("euler", "quat"), "XYZ")
        # as featurize stores them: float32, quaternions sign-continuous
        euler = reps["euler"].astype(np.float32)
        quat = continue_quat_signs(reps["quat"], None).astype(np.float32)
        bpm = music_bpm(parse_sequence_name(path.stem).music_id)
        bounds = measure_bounds(motion.n_frames, bpm, 60.0)
        sequences.append((euler, quat, motion.trans_m, bounds))
    assert sum(len(s[3]) for s in sequences) == 27
    found = {}
    for n in (3, 5, 9):
        truth, recon = [], []
        for euler, quat, trans, bounds in sequences:
            lengths = bounds[:, 1] - bounds[:, 0]
            keyframes = np.stack([even_indices(int(length), n) for length in lengths])
            seg = segment_map(bounds[:, 0], lengths, keyframes)
            rec = linear_slerp(quat, trans, seg, "XYZ", truth_euler=euler)
            rows = np.concatenate([trans, euler.reshape(len(euler), -1)], axis=1)
            truth.append(rows[seg.frame])
            recon.append(rec.euler75())
        found[n] = mse_euler75(np.concatenate(truth), np.concatenate(recon))
    for n, expected in ((3, 0.336), (5, 0.209), (9, 0.084)):
        assert abs(found[n] - expected) < 1e-3, found
