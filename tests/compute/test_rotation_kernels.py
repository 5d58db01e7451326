"""The compiled rotation conversions against scipy's Rotation called directly (every Euler order,
intrinsic and extrinsic, Tait-Bryan and proper, small, large, zero and gimbal-locked rotations),
and the span-wise quaternion sign continuity against the per-sequence numpy function; the
one-pass float32 representations (featurize's) bit-equal to the float64 pass, sign continuity
and cast done afterwards."""

from __future__ import annotations

import warnings

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from dancedata.compute.motion_representations import representations_from_axis_angle
from dancedata.compute.rotation_kernels import (
    euler_order_params,
    quat_sign_continuous_spans,
    rotation_representations,
    rotations_from_axis_angle,
    span_links,
)
from dancedata.compute.rotations import quat_sign_continuous

ORDERS = [a + b + c for a in "xyz" for b in "xyz" for c in "xyz" if a != b and b != c]
ORDERS += [o.upper() for o in ORDERS]  # 12 extrinsic, 12 intrinsic


def _cases(n: int = 3000) -> np.ndarray:
    rng = np.random.default_rng(7)
    aa = rng.normal(0, 1.5, (n, 3))
    aa[0] = 0.0
    aa[1] = [1e-4, -2e-4, 5e-5]  # below scipy's small-angle switch (1e-3)
    aa[2] = [np.pi, 0, 0]  # w = 0: the canonical sign rule
    aa[3] = [0, -np.pi, 0]
    aa[4] = [5.0, 1.0, -2.0]  # beyond pi: w < 0
    return aa


def _angle_diff(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    d = np.abs(a - b) % (2 * np.pi)
    return np.minimum(d, 2 * np.pi - d)


@pytest.mark.parametrize("order", ORDERS)
def test_equal_to_scipy(order):
    aa = _cases()
    got = rotations_from_axis_angle(aa[:, None, :], euler_order=order)
    rot = Rotation.from_rotvec(aa)
    np.testing.assert_allclose(
        got["quat"][:, 0], rot.as_quat(canonical=True)[:, [3, 0, 1, 2]], rtol=0, atol=1e-15
    )
    np.testing.assert_allclose(got["rotmat"][:, 0], rot.as_matrix(), rtol=0, atol=1e-15)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", UserWarning)  # scipy's gimbal-lock warning
        ref = rot.as_euler(order)
    assert _angle_diff(got["euler"][:, 0], ref).max() < 1e-12


@pytest.mark.parametrize("order", ["XYZ", "zxz", "YXY", "xzy"])
def test_gimbal_lock_gives_the_same_rotation_as_scipy(order):
    """Middle angle at its singular value: both set the third angle to 0; the angles agree and
    describe the same rotation."""
    symmetric = order[0].lower() == order[2].lower()
    middles = [0.0, np.pi] if symmetric else [np.pi / 2, -np.pi / 2]
    rng = np.random.default_rng(1)
    angles = []
    for middle in middles:
        for _ in range(50):
            angles.append([rng.uniform(-3, 3), middle, rng.uniform(-3, 3)])
    rot = Rotation.from_euler(order, angles)
    got = rotations_from_axis_angle(rot.as_rotvec()[:, None, :], euler_order=order)
    back = Rotation.from_euler(order, got["euler"][:, 0])
    assert np.all((back * rot.inv()).magnitude() < 1e-9)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", UserWarning)
        ref = rot.as_euler(order)
    assert _angle_diff(got["euler"][:, 0], ref).max() < 1e-9


def test_per_joint_orders_and_float32_input():
    aa = _cases(400).reshape(100, 4, 3).astype(np.float32)
    orders = ["ZXY", "XYZ", "zyx", "ZXY"]
    got = rotations_from_axis_angle(aa, euler_order=orders)
    for j, order in enumerate(orders):
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", UserWarning)
            ref = Rotation.from_rotvec(aa[:, j].astype(np.float64)).as_euler(order)
        assert _angle_diff(got["euler"][:, j], ref).max() < 1e-12
    reps = representations_from_axis_angle(aa, ["rotmat", "rot6d", "rot6d_rows"], "XYZ")
    rotmat = Rotation.from_rotvec(aa.reshape(-1, 3).astype(np.float64)).as_matrix()
    np.testing.assert_allclose(reps["rotmat"].reshape(-1, 3, 3), rotmat, atol=1e-15)
    np.testing.assert_array_equal(reps["rot6d"][..., :3], reps["rotmat"][..., :, 0])
    np.testing.assert_array_equal(reps["rot6d_rows"][..., 3:], reps["rotmat"][..., 1, :])


def test_sign_continuity_per_span_equals_per_sequence_numpy():
    rng = np.random.default_rng(2)
    quat = rng.normal(0, 1, (500, 3, 4))
    quat /= np.linalg.norm(quat, axis=-1, keepdims=True)
    bounds = np.array([[0, 120], [120, 121], [121, 400], [400, 500]])
    got = quat_sign_continuous_spans(quat, bounds)
    ref = np.concatenate([quat_sign_continuous(quat[a:b]) for a, b in bounds])
    np.testing.assert_array_equal(got, ref)
    assert np.array_equal(quat, quat.copy())  # the input is not modified
    with pytest.raises(ValueError, match="outside"):
        quat_sign_continuous_spans(quat, np.array([[0, 501]]))


def test_order_params_refuse_nonsense():
    assert euler_order_params("XYZ").tolist() == [2, 1, 0, 0, -1, 0]  # odd permutation z, y, x
    for bad in ("XYz", "XXY", "abc", "XY"):
        with pytest.raises(ValueError):
            euler_order_params(bad)


ALL = ("rotmat", "euler", "quat", "rot6d", "rot6d_rows")


def _float64_then_cast(aa, orders, bounds):  # noqa: ANN001, ANN202
    """The earlier featurize path: float64 arrays, signs in a second pass, then float32."""
    reps = representations_from_axis_angle(aa, ALL, orders)
    if bounds is not None:
        reps["quat"] = quat_sign_continuous_spans(reps["quat"], bounds)
    return {k: v.astype(np.float32) for k, v in reps.items()}


@pytest.mark.parametrize("dtype", [np.float32, np.float64])
def test_one_pass_float32_is_bit_equal_to_float64_then_cast(dtype):
    rng = np.random.default_rng(11)
    aa = np.concatenate([_cases(600).reshape(200, 3, 3), rng.normal(0, 2, (300, 3, 3))])
    aa = aa.astype(dtype)
    orders = ["XYZ", "zyx", "ZXZ"]
    # sequences of several lengths, one of a single frame, frames 0-4 and 495-499 in none
    bounds = np.array([[5, 120], [120, 121], [121, 400], [400, 495]])
    for b in (bounds, bounds[::-1], None):
        got = rotation_representations(aa, ALL, orders, bounds=b)
        want = _float64_then_cast(aa, orders, b)
        for k in ALL:
            assert got[k].dtype == np.float32, k
            assert got[k].tobytes() == want[k].tobytes(), (k, b is None)
    assert not np.array_equal(
        got["quat"], rotation_representations(aa, ALL, orders, bounds=bounds)["quat"]
    )
    only = rotation_representations(aa, ["rot6d", "quat"], "XYZ", bounds=bounds)
    assert list(only) == ["rot6d", "quat"]
    np.testing.assert_array_equal(only["rot6d"], _float64_then_cast(aa, "XYZ", bounds)["rot6d"])


def test_one_pass_overlapping_spans_fall_back_to_span_after_span():
    rng = np.random.default_rng(3)
    aa = rng.normal(0, 2, (300, 2, 3))
    bounds = np.array([[0, 200], [100, 300]])
    assert span_links(bounds, 300) is None
    got = rotation_representations(aa, ["quat"], "XYZ", bounds=bounds)["quat"]
    assert got.tobytes() == _float64_then_cast(aa, "XYZ", bounds)["quat"].tobytes()
    with pytest.raises(ValueError, match="outside"):
        rotation_representations(aa, ["quat"], "XYZ", bounds=np.array([[0, 301]]))
    with pytest.raises(ValueError, match="unknown"):
        rotation_representations(aa, ["quaternion"], "XYZ")


def test_span_links_mark_frames_that_continue_a_sequence():
    links = span_links(np.array([[2, 5], [5, 6], [6, 9]]), 10)
    assert links.tolist() == [0, 0, 0, 1, 1, 0, 0, 1, 1, 0]
