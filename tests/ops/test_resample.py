"""Resampling: exact decimation for integer ratios, SLERP (against scipy's Slerp) and linear
translation otherwise, and the documented frame-count formula."""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy.spatial.transform import Rotation, Slerp

from dancedata.compute.resample import (
    decimation_step,
    resample_motion,
    resample_positions,
    resampled_frame_count,
    slerp,
)
from dancedata.io.bvh import euler_degrees, read_bvh
from dancedata.ops.bvh_clip import local_rotmats, resample_clip


def _random_motion(n_frames: int, n_joints: int, seed: int) -> tuple[np.ndarray, np.ndarray]:
    """Smoothly varying quaternions (wxyz) with random sign flips, and translations."""
    rng = np.random.default_rng(seed)
    base = Rotation.random(n_joints, random_state=seed)
    steps = rng.normal(scale=0.2, size=(n_frames, n_joints, 3)).cumsum(axis=0)
    rots = Rotation.from_rotvec(steps.reshape(-1, 3)) * Rotation.concatenate([base] * n_frames)
    quat = rots.as_quat().reshape(n_frames, n_joints, 4)[..., [3, 0, 1, 2]]
    quat *= rng.choice([-1.0, 1.0], size=(n_frames, n_joints, 1))
    return quat, rng.normal(size=(n_frames, 3)).cumsum(axis=0)


@pytest.mark.real_data
def test_120_to_30_keeps_every_fourth_frame_exactly(real_data):
    clip = read_bvh(real_data / "bvh" / "01_01.bvh")  # Frame Time .0083333 = 120.0005 fps
    out = resample_clip(clip, 30)
    assert out.n_frames == (2752 - 1) // 4 + 1 == 688
    np.testing.assert_array_equal(out.values, clip.values[::4])
    assert out.frame_time_s == pytest.approx(4 * 0.0083333)
    assert out.skeleton is clip.skeleton


def test_decimation_on_arrays_is_bit_exact():
    quat, trans = _random_motion(121, 3, seed=0)
    res = resample_motion(quat, trans, 120.0, 30.0)
    assert res.method == "decimate" and res.step == 4
    np.testing.assert_array_equal(res.quat, quat[::4])
    np.testing.assert_array_equal(res.translations, trans[::4])
    np.testing.assert_array_equal(res.source_positions, np.arange(31) * 4)


@pytest.mark.parametrize(
    ("n", "src", "dst", "expected"),
    [
        (2752, 120.0005, 30, 688),  # decimation by 4: floor(2751 / 4) + 1
        (9, 120, 30, 3),
        (8, 120, 30, 2),
        (10, 120, 50, 4),  # floor(9 * 50 / 120) + 1 = floor(3.75) + 1
        (121, 120, 50, 51),  # floor(120 * 50 / 120) + 1
        (11, 30, 60, 21),  # upsampling: floor(10 * 2) + 1
        (5, 60, 60, 5),
        (1, 120, 7, 1),
        (0, 120, 30, 0),
    ],
)
def test_frame_count_formula(n, src, dst, expected):
    assert resampled_frame_count(n, src, dst) == expected
    if n:
        assert len(resample_positions(n, src, dst)) == expected
        assert resample_positions(n, src, dst)[-1] <= n - 1


def test_decimation_step():
    assert decimation_step(120, 30) == 4
    assert decimation_step(1 / 0.008333, 30) == 4  # 120.005 fps, within 0.1 %
    assert decimation_step(125, 30) is None
    assert decimation_step(30, 60) is None
    assert decimation_step(60, 60) == 1


@settings(max_examples=25, deadline=None)
@given(st.integers(0, 10_000), st.sampled_from([(120, 50), (125, 30), (30, 45), (60, 25)]))
def test_slerp_path_matches_scipy(seed, rates):
    src, dst = rates
    quat, trans = _random_motion(23, 4, seed)
    res = resample_motion(quat, trans, src, dst)
    assert res.method == "slerp"
    times_in = np.arange(23) / src
    times_out = np.arange(resampled_frame_count(23, src, dst)) / dst
    assert res.quat.shape == (len(times_out), 4, 4)
    for j in range(4):
        rots = Rotation.from_quat(quat[:, j][:, [1, 2, 3, 0]])
        expected = Slerp(times_in, rots)(np.minimum(times_out, times_in[-1])).as_matrix()
        got = Rotation.from_quat(res.quat[:, j][:, [1, 2, 3, 0]]).as_matrix()
        np.testing.assert_allclose(got, expected, atol=1e-9)
    for axis in range(3):
        np.testing.assert_allclose(
            res.translations[:, axis], np.interp(times_out, times_in, trans[:, axis]), atol=1e-9
        )


def test_slerp_endpoints_and_midpoint():
    q0 = np.array([1.0, 0, 0, 0])
    q1 = -Rotation.from_euler("z", 90, degrees=True).as_quat()[[3, 0, 1, 2]]  # opposite sign
    mid = slerp(q0, q1, 0.5)
    yaw = Rotation.from_quat(mid[[1, 2, 3, 0]]).as_euler("zyx", degrees=True)[0]
    assert yaw == pytest.approx(45)
    np.testing.assert_allclose(np.abs(slerp(q0, q1, 1.0)), np.abs(q1), atol=1e-12)
    np.testing.assert_allclose(slerp(q0, q0, 0.3), q0)


@pytest.mark.real_data
def test_resample_clip_slerp_path_on_real_file(real_data):
    clip = read_bvh(real_data / "bvh" / "test_mocapbank.bvh")
    clip = dataclasses.replace(clip, frame_time_s=1 / 30)  # the file says 0.033333
    out = resample_clip(clip, 24.0)
    assert out.n_frames == math.floor(454 * 24 / clip.fps + 1e-9) + 1
    # Rotations at output frame i equal scipy's Slerp of the source at time i / 24.
    times_in = np.arange(clip.n_frames) * clip.frame_time_s
    times_out = np.arange(out.n_frames) / 24.0
    src, got = local_rotmats(clip), local_rotmats(out)
    for j in (0, 5, 12):
        expected = Slerp(times_in, Rotation.from_matrix(src[:, j]))(times_out)
        err = (Rotation.from_matrix(got[:, j]) * expected.inv()).magnitude()
        assert np.degrees(err).max() < 1e-4
    # Where output frames coincide with source frames (every 5th output = 4th input at 30→24),
    # the Euler channels come back as they were.
    np.testing.assert_allclose(euler_degrees(out)[::4], euler_degrees(clip)[::5], atol=1e-9)
    np.testing.assert_allclose(out.values[::4], clip.values[::5], atol=1e-9)
