"""Rotation conversions against scipy, and the 6D / quaternion conventions."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from dancedata.compute import rotations as rot


@pytest.fixture
def rotvecs():
    rng = np.random.default_rng(1)
    r = Rotation.random(600, random_state=rng)
    return r.as_rotvec().reshape(50, 12, 3)


def test_rotmat_matches_scipy(rotvecs):
    ours = rot.axis_angle_to_rotmat(rotvecs)
    ref = Rotation.from_rotvec(rotvecs.reshape(-1, 3)).as_matrix().reshape(50, 12, 3, 3)
    np.testing.assert_allclose(ours, ref, atol=1e-12)


def test_quat_is_wxyz_of_scipy(rotvecs):
    ours = rot.axis_angle_to_quat(rotvecs).reshape(-1, 4)
    xyzw = Rotation.from_rotvec(rotvecs.reshape(-1, 3)).as_quat()
    same = np.allclose(ours, xyzw[:, [3, 0, 1, 2]], atol=1e-12)
    flipped = np.allclose(ours, -xyzw[:, [3, 0, 1, 2]], atol=1e-12)
    assert same or flipped
    np.testing.assert_allclose(
        np.abs(np.sum(ours * xyzw[:, [3, 0, 1, 2]], axis=1)), 1.0, atol=1e-12
    )


@pytest.mark.parametrize("order", ["XYZ", "ZXY", "zyx", "YZX"])
def test_euler_round_trip_matches_scipy(rotvecs, order):
    euler = rot.axis_angle_to_euler(rotvecs, order)
    ref = Rotation.from_rotvec(rotvecs.reshape(-1, 3)).as_euler(order).reshape(euler.shape)
    np.testing.assert_allclose(euler, ref, atol=1e-10)
    back = rot.euler_to_rotmat(euler, order)
    np.testing.assert_allclose(back, rot.axis_angle_to_rotmat(rotvecs), atol=1e-10)


def test_rot6d_is_first_two_columns_and_round_trips(rotvecs):
    matrix = rot.axis_angle_to_rotmat(rotvecs)
    six = rot.rotmat_to_rot6d(matrix)
    np.testing.assert_array_equal(six[..., :3], matrix[..., :, 0])
    np.testing.assert_array_equal(six[..., 3:], matrix[..., :, 1])
    np.testing.assert_allclose(rot.rot6d_to_rotmat(six), matrix, atol=1e-12)


def test_quaternion_sign_continuity_keeps_rotations():
    rng = np.random.default_rng(2)
    # A smooth path whose canonical (w >= 0) quaternions jump sign when the angle passes pi.
    angles = np.linspace(0, 4 * np.pi, 400)
    axis = np.array([0.3, -0.5, 0.8]) / np.linalg.norm([0.3, -0.5, 0.8])
    quat = rot.axis_angle_to_quat(angles[:, None] * axis)
    quat *= np.where(rng.random(400) < 0.5, -1.0, 1.0)[:, None]
    smooth = rot.quat_sign_continuous(quat)
    assert np.all(np.sum(smooth[1:] * smooth[:-1], axis=-1) >= 0)
    np.testing.assert_allclose(np.abs(np.sum(smooth * quat, axis=-1)), 1.0, atol=1e-12)
