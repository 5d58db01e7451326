"""Laban Time/Space/Flow efforts and angular acceleration/jerk: against brute-force loops written
from the formulas (Larboulette & Gibet 2015), closed forms on analytic motions, scipy's rotation
composition for the angular derivatives, and through featurize on a real store."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from dancedata.compute.laban import (
    SPACE_FLOOR_M,
    effort_summary,
    laban_flow,
    laban_space,
    laban_time,
    window_frames,
)
from dancedata.compute.motion_features import angular_acceleration, angular_jerk
from dancedata.metrics.laban import laban_effort_distance


def _brute(positions: np.ndarray, fps: float, window: int):
    """Per frame t and joint k, from the definitions, with explicit loops."""
    n, j = positions.shape[:2]
    half = window // 2
    time = np.zeros((n, j))
    flow = np.zeros((n, j))
    space = np.zeros((n, j))
    for t in range(n):
        lo, hi = max(0, t - half), min(n, t + half + 1)
        for k in range(j):
            p = positions[:, k]
            accs = [
                np.linalg.norm(p[i + 2] - 2 * p[i + 1] + p[i]) * fps**2
                for i in range(lo, hi)
                if i + 2 < n
            ]
            jerks = [
                np.linalg.norm(p[i + 3] - 3 * p[i + 2] + 3 * p[i + 1] - p[i]) * fps**3
                for i in range(lo, hi)
                if i + 3 < n
            ]
            # a window past the last defined derivative takes the last one (as documented)
            time[t, k] = (
                np.mean(accs)
                if accs
                else np.linalg.norm(p[n - 1] - 2 * p[n - 2] + p[n - 3]) * fps**2
            )
            flow[t, k] = (
                np.mean(jerks)
                if jerks
                else np.linalg.norm(p[n - 1] - 3 * p[n - 2] + 3 * p[n - 3] - p[n - 4]) * fps**3
            )
            path = sum(np.linalg.norm(p[i + 1] - p[i]) for i in range(lo, hi - 1))
            net = np.linalg.norm(p[hi - 1] - p[lo])
            space[t, k] = 1.0 if path < SPACE_FLOOR_M else max(1.0, path / max(net, SPACE_FLOOR_M))
    return time, space, flow


def test_efforts_equal_brute_force_loops():
    rng = np.random.default_rng(3)
    positions = np.cumsum(rng.normal(0, 0.01, (47, 4, 3)), axis=0)
    positions[:, 3] = positions[0, 3]  # one joint standing still
    fps, window = 30.0, 9
    time, space, flow = _brute(positions, fps, window)
    np.testing.assert_allclose(laban_time(positions, fps, window=window), time, rtol=1e-10)
    np.testing.assert_allclose(laban_flow(positions, fps, window=window), flow, rtol=1e-10)
    np.testing.assert_allclose(laban_space(positions, window=window), space, rtol=1e-10)
    assert np.all(laban_space(positions, window=window)[:, 3] == 1.0)


def test_closed_forms():
    fps = 60.0
    t = np.arange(121) / fps
    # Uniform acceleration a = 2 m/s² along x: Time = 2, Flow = 0, Space = 1 (straight line).
    line = np.zeros((121, 1, 3))
    line[:, 0, 0] = t**2
    window = window_frames(1.0, fps)
    np.testing.assert_allclose(laban_time(line, fps, window=window), 2.0, rtol=1e-8)
    np.testing.assert_allclose(laban_flow(line, fps, window=window), 0.0, atol=1e-6)
    np.testing.assert_allclose(laban_space(line, window=window)[5:-5], 1.0, rtol=1e-12)
    # A circle of radius r at ω rad/s: |a| = r ω², |j| = r ω³ (up to the finite difference).
    r, w = 0.3, 2 * np.pi
    circle = np.zeros((121, 1, 3))
    circle[:, 0, 0], circle[:, 0, 1] = r * np.cos(w * t), r * np.sin(w * t)
    np.testing.assert_allclose(laban_time(circle, fps, window=window), r * w**2, rtol=2e-3)
    np.testing.assert_allclose(laban_flow(circle, fps, window=window), r * w**3, rtol=5e-3)
    # A whole turn in the 61-frame (60-step) window: the path is 60 chords of 2π/60, the net
    # displacement 0, floored at 1 mm.
    mid = laban_space(circle, window=window)[60, 0]
    assert mid == pytest.approx(60 * 2 * r * np.sin(np.pi / 60) / SPACE_FLOOR_M, rel=1e-9)


def test_window_frames_is_odd_and_refuses_nonsense():
    assert window_frames(1.0, 60) == 61
    assert window_frames(0.5, 30) == 15
    assert window_frames(0.01, 30) == 3
    for bad in ((0.0, 30), (1.0, float("nan")), (1.0, 0)):
        with pytest.raises(ValueError):
            window_frames(*bad)


def test_angular_derivatives_match_scipy_composition():
    """ω from scipy's relative rotations (R[t+1] R[t]⁻¹ as a rotation vector × fps), then its
    forward differences: agrees with the quaternion formula to first order."""
    fps = 120.0
    t = np.arange(40) / fps
    rotvec = np.stack([0.4 * np.sin(3 * t), 0.2 * t, 0.1 * np.cos(2 * t)], axis=1)
    rot = Rotation.from_rotvec(rotvec)
    quat_wxyz = np.roll(rot.as_quat(), 1, axis=1)[:, None, :]
    omega = (rot[1:] * rot[:-1].inv()).as_rotvec() * fps
    acc_ref = np.diff(omega, axis=0) * fps
    jerk_ref = np.diff(omega, n=2, axis=0) * fps**2
    acc = angular_acceleration(quat_wxyz, fps)[:, 0]
    jerk = angular_jerk(quat_wxyz, fps)[:, 0]
    assert acc.shape == (38, 3) and jerk.shape == (37, 3)
    np.testing.assert_allclose(acc, acc_ref, atol=2e-2 * np.abs(acc_ref).max())
    np.testing.assert_allclose(jerk, jerk_ref, atol=5e-2 * np.abs(jerk_ref).max())


def test_effort_distance_is_a_symmetric_relative_difference():
    a = {"time": 2.0, "space": 1.5, "flow": 40.0, "weight": 10.0}
    assert laban_effort_distance(a, a) == 0.0
    b = {"time": 4.0, "space": 1.5, "flow": 40.0, "weight": 10.0}
    # |2 − 4| / ((2 + 4) / 2) = 2/3 on one effort of four
    assert laban_effort_distance(a, b) == pytest.approx((2 / 3) / 4)
    assert laban_effort_distance(a, b) == laban_effort_distance(b, a)
    with pytest.raises(ValueError, match="efforts differ"):
        laban_effort_distance(a, {"time": 1.0})
    summary = effort_summary({"time": np.ones((10, 3)), "weight": np.full(10, 2.0)})
    assert summary == {"time": 3.0, "weight": 2.0}


@pytest.mark.slow
@pytest.mark.real_data
def test_featurize_writes_laban_and_angular_derivative_arrays(real_data, tmp_path):
    """On the real CMU walk (BVH at 120 fps): featurize writes the efforts and derivatives, and
    the stored arrays equal the pure functions on the stored positions (float32 rounding)."""
    import dancedata
    from tests.helpers import run_cli

    store = tmp_path / "store"
    bvh = real_data / "bvh" / "01_01.bvh"
    run_cli("ingest", "bvh", str(bvh), "--store", str(store), "--units", "0.056444", "--quiet")
    run_cli(
        "featurize",
        str(store),
        "--motion-families",
        "positions,laban,angular_derivatives",
        "--quiet",
    )
    ds = dancedata.open_store(store)
    seq = ds.seq_ids()[0]
    positions = ds.motion(seq, "positions").astype(np.float64)
    fps = float(ds.group_attrs("motion")["fps"])
    window = window_frames(1.0, fps)
    np.testing.assert_allclose(
        ds.motion(seq, "laban_time"), laban_time(positions, fps, window=window), rtol=1e-4
    )
    np.testing.assert_allclose(
        ds.motion(seq, "laban_space_sum"),
        laban_space(positions, window=window).sum(axis=1),
        rtol=1e-4,
    )
    n_joints = positions.shape[1]
    assert ds.motion(seq, "angular_jerk").shape == (positions.shape[0], n_joints, 3)
    attrs = ds.group_attrs("motion/laban_flow")
    assert attrs["units"] == "m/s^3" and attrs["window_s"] == 1.0
