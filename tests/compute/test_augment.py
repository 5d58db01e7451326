"""Mirror and yaw augmentation: exact involution, agreement with forward kinematics of the
augmented motion (an independent path: rotations in, positions out), invariance of the kinetic
and geometric features under yaw, on the real AIST++ motions and on synthetic ones."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from dancedata.compute.augment import (
    mirror_axis_angle,
    mirror_pairs,
    mirror_points,
    yaw_axis_angle,
    yaw_points,
)
from dancedata.compute.fk import forward_kinematics
from dancedata.compute.motion_features import geometric_features, kinetic_features
from dancedata.compute.smpl import SMPL_JOINTS, SMPL_PARENTS, SMPL_REST_OFFSETS_M
from dancedata.io.aist import read_motion


def _fk(axis_angle: np.ndarray, trans: np.ndarray) -> np.ndarray:
    rotmats = Rotation.from_rotvec(axis_angle.reshape(-1, 3)).as_matrix()
    rotmats = rotmats.reshape(*axis_angle.shape[:2], 3, 3)
    return forward_kinematics(SMPL_PARENTS, SMPL_REST_OFFSETS_M, rotmats, trans)


def _motion(seed: int = 0, n: int = 90):
    rng = np.random.default_rng(seed)
    aa = rng.normal(0, 0.4, (n, 24, 3))
    trans = np.cumsum(rng.normal(0, 0.01, (n, 3)), axis=0) + [0.3, 0.9, -0.2]
    return aa, trans


def test_smpl_pairs_swap_left_and_right():
    perm = mirror_pairs(SMPL_JOINTS)
    named = {SMPL_JOINTS[i]: SMPL_JOINTS[j] for i, j in enumerate(perm)}
    assert named["left_hip"] == "right_hip" and named["right_wrist"] == "left_wrist"
    assert named["pelvis"] == "pelvis" and named["head"] == "head"
    assert sum(i != j for i, j in enumerate(perm)) == 18  # 9 pairs


@pytest.mark.parametrize(
    "names,expected",
    [
        (["Hips", "LeftUpLeg", "RightUpLeg", "Spine"], [0, 2, 1, 3]),  # CMU
        (["hip", "lThigh", "rThigh", "abdomen"], [0, 2, 1, 3]),  # DAZ
        (["root", "l_knee", "r_knee"], [0, 2, 1]),
        (["Arm.L", "Arm.R", "Neck"], [1, 0, 2]),  # Blender
        (["LHip", "RHip", "Lower"], [1, 0, 2]),
    ],
)
def test_pairs_by_name_on_common_rigs(names, expected):
    assert mirror_pairs(names).tolist() == expected


def test_mirror_twice_is_identity_bit_for_bit():
    aa, trans = _motion()
    perm = mirror_pairs(SMPL_JOINTS)
    once = mirror_axis_angle(aa, trans, perm)
    twice = mirror_axis_angle(*once, perm)
    assert np.array_equal(twice[0], aa) and np.array_equal(twice[1], trans)
    p = _fk(aa, trans)
    assert np.array_equal(mirror_points(mirror_points(p, perm), perm), p)


def test_mirrored_rotations_give_mirrored_positions():
    """FK of the mirrored rotations = the mirrored FK positions (SMPL_REST_OFFSETS_M is
    mirror-symmetric), so the rotation reflection −M v is right."""
    aa, trans = _motion(1)
    perm = mirror_pairs(SMPL_JOINTS)
    offsets = SMPL_REST_OFFSETS_M
    assert np.allclose(mirror_points(offsets[None], perm)[0], offsets)
    m_aa, m_trans = mirror_axis_angle(aa, trans, perm)
    np.testing.assert_allclose(_fk(m_aa, m_trans), mirror_points(_fk(aa, trans), perm), atol=1e-12)


@pytest.mark.parametrize("angle", [0.3, -2.0, np.pi])
def test_yaw_commutes_with_fk_and_keeps_kinetic_and_geometric_features(angle):
    aa, trans = _motion(2)
    p = _fk(aa, trans)
    y_aa, y_trans = yaw_axis_angle(aa, trans, angle)
    turned = _fk(y_aa, y_trans)
    np.testing.assert_allclose(turned, yaw_points(p, angle), atol=1e-12)
    for mode in ("parity", "corrected"):
        np.testing.assert_allclose(
            kinetic_features(turned, 60.0, mode=mode),
            kinetic_features(p, 60.0, mode=mode),
            rtol=1e-9,
            atol=1e-9,
        )
    np.testing.assert_array_equal(geometric_features(turned), geometric_features(p))


@pytest.mark.real_data
def test_on_real_aist_motions(real_data):
    perm = mirror_pairs(SMPL_JOINTS)
    for path in sorted((real_data / "aist" / "motions").glob("*.pkl"))[:3]:
        motion = read_motion(path)
        aa = motion.axis_angle.astype(np.float64)[:240]
        trans = motion.trans_m.astype(np.float64)[:240]
        twice = mirror_axis_angle(*mirror_axis_angle(aa, trans, perm), perm)
        assert np.array_equal(twice[0], aa), path.name
        p = _fk(aa, trans)
        y_aa, y_trans = yaw_axis_angle(aa, trans, 1.1)
        turned = _fk(y_aa, y_trans)
        np.testing.assert_allclose(
            kinetic_features(turned, 60.0, mode="parity"),
            kinetic_features(p, 60.0, mode="parity"),
            rtol=1e-8,
            atol=1e-8,
        )


def test_refuses_bad_axes_and_angles():
    aa, trans = _motion(3, n=4)
    with pytest.raises(ValueError, match="axis"):
        mirror_axis_angle(aa, trans, mirror_pairs(SMPL_JOINTS), lateral_axis=3)
    with pytest.raises(ValueError, match="finite"):
        yaw_points(np.zeros((2, 1, 3)), float("nan"))
    with pytest.raises(ValueError, match="repeat"):
        mirror_pairs(["LeftArm", "RightArm", "LeftArm"])
