"""BVH → arrays → BVH: same hierarchy, same channels (angles within 1e-4°), and the written
file parses again; also through rotation matrices, and Euler branch/continuity handling."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy.spatial.transform import Rotation

from dancedata.compute.euler_continuity import euler_alternative, euler_continuous, euler_nearest
from dancedata.compute.fk import forward_kinematics
from dancedata.io.bvh import (
    BvhClip,
    BvhSkeleton,
    clip_from_arrays,
    euler_degrees,
    format_bvh,
    local_translations,
    make_skeleton,
    parse_bvh,
    read_bvh,
    scale_clip,
    write_bvh,
)
from dancedata.ops.bvh_clip import clip_from_rotations, local_rotmats, world_positions

NAMES = [
    "01_01.bvh",
    "AV_8Walk_Meredith_HVHA_Rep1.bvh",
    "test_freebvh.bvh",
    "test_mocapbank.bvh",
    "freya_edit.bvh",
]


def _rotation_rows(clip: BvhClip) -> np.ndarray:
    """Boolean mask of rotation columns."""
    return np.array([c.endswith("rotation") for chans in clip.skeleton.channels for c in chans])


@pytest.mark.real_data
@pytest.mark.parametrize("name", NAMES)
def test_roundtrip_through_euler_arrays(real_data, name, tmp_path):
    clip = read_bvh(real_data / "bvh" / name)
    rebuilt = clip_from_arrays(
        clip.skeleton, clip.frame_time_s, euler_degrees(clip), local_translations(clip)
    )
    out = tmp_path / "out.bvh"
    write_bvh(rebuilt, out)
    again = read_bvh(out)
    assert again.skeleton.same_hierarchy(clip.skeleton)
    assert again.frame_time_s == clip.frame_time_s
    assert again.n_frames == clip.n_frames
    rot = _rotation_rows(clip)
    assert np.abs(again.values[:, rot] - clip.values[:, rot]).max() < 1e-4
    assert np.abs(again.values[:, ~rot] - clip.values[:, ~rot]).max() < 1e-5
    # The exported file parses again to the same text.
    assert format_bvh(again) == out.read_text()


@pytest.mark.slow
@pytest.mark.real_data
@pytest.mark.parametrize("name", NAMES)
def test_roundtrip_through_rotation_matrices(real_data, name):
    clip = read_bvh(real_data / "bvh" / name)
    euler = euler_degrees(clip)
    rotmats = local_rotmats(clip)
    trans = local_translations(clip)
    nearest = clip_from_rotations(clip.skeleton, clip.frame_time_s, rotmats, trans, euler)
    assert np.abs(euler_degrees(nearest) - euler).max() < 1e-4
    text = format_bvh(nearest)
    assert parse_bvh(text).skeleton.same_hierarchy(clip.skeleton)

    # Without a reference the curves are continuous and the rotations unchanged.
    cont = clip_from_rotations(clip.skeleton, clip.frame_time_s, rotmats, trans)
    err = (
        Rotation.from_matrix(local_rotmats(cont).reshape(-1, 3, 3))
        * Rotation.from_matrix(rotmats.reshape(-1, 3, 3)).inv()
    )
    assert np.degrees(err.magnitude()).max() < 1e-6
    jumps = np.abs(np.diff(euler_degrees(cont), axis=0)).max()
    original = np.abs(np.diff(np.unwrap(euler, period=360, axis=0), axis=0)).max()
    assert jumps <= original + 1e-6
    np.testing.assert_allclose(world_positions(cont), world_positions(clip), atol=1e-9)


@pytest.mark.parametrize("order", ["ZYX", "ZXY", "XYZ"])
def test_export_rotations_of_a_rig_without_channels(order):
    """Store-style data (rotation matrices + root translation, SMPL-like parents) → BVH text →
    parsed again: same rotations and the same FK positions."""
    parents = (-1, 0, 0, 0, 1, 2, 3, 4)
    offsets = np.random.default_rng(2).normal(size=(8, 3))
    rotmats = Rotation.random(40 * 8, random_state=7).as_matrix().reshape(40, 8, 3, 3)
    root = np.random.default_rng(3).normal(size=(40, 3))
    skel = make_skeleton([f"j{i}" for i in range(8)], parents, offsets, rotation_order=order)
    trans = np.broadcast_to(offsets, (40, 8, 3)).copy()
    trans[:, 0] = root
    clip = parse_bvh(format_bvh(clip_from_rotations(skel, 1 / 60, rotmats, trans)))
    assert set(clip.skeleton.rotation_orders) == {order}
    # The file lists joints depth first (j0 j1 j4 j7 j2 j5 j3 j6): compare by name.
    idx = [clip.skeleton.names.index(f"j{i}") for i in range(8)]
    got = local_rotmats(clip)[:, idx]
    err = (
        Rotation.from_matrix(got.reshape(-1, 3, 3))
        * Rotation.from_matrix(rotmats.reshape(-1, 3, 3)).inv()
    )
    assert np.degrees(err.magnitude()).max() < 1e-4
    expected = forward_kinematics(parents, offsets, rotmats, root_translation=root)
    np.testing.assert_allclose(world_positions(clip)[:, idx], expected, atol=1e-5)


def test_writer_handles_non_depth_first_joint_order_and_end_sites():
    skel = BvhSkeleton(
        names=("root", "a", "b", "a_child"),
        parents=(-1, 0, 0, 1),  # depth-first order would be root, a, a_child, b
        offsets=np.arange(12.0).reshape(4, 3),
        channels=(("Xposition", "Yposition", "Zposition", "Yrotation"), ("Zrotation",), (),
                  ("Xrotation", "Zrotation")),
        end_sites=(np.zeros((0, 3)), np.zeros((0, 3)), np.ones((2, 3)), np.zeros((0, 3))),
    )  # fmt: skip
    values = np.random.default_rng(0).uniform(-180, 180, size=(3, skel.n_channels))
    clip = BvhClip(skel, np.float64(1 / 30), values)  # a numpy scalar prints as a plain float
    again = parse_bvh(format_bvh(clip))
    assert again.frame_time_s == 1 / 30
    assert again.skeleton.names == ("root", "a", "a_child", "b")
    assert again.skeleton.parents == (-1, 0, 1, 0)
    perm = [0, 1, 3, 2]
    for new, old in enumerate(perm):
        assert again.skeleton.channels[new] == skel.channels[old]
        np.testing.assert_array_equal(again.skeleton.end_sites[new], skel.end_sites[old])
    moved = world_positions(again)[:, perm.index(3)]
    np.testing.assert_allclose(moved, world_positions(clip)[:, 3], atol=1e-5)


def test_scale_clip_scales_lengths_not_angles():
    clip = parse_bvh(
        "HIERARCHY\nROOT r\n{\nOFFSET 1 2 3\nCHANNELS 4 Xposition Yposition Zposition Zrotation\n"
        "End Site\n{\nOFFSET 0 10 0\n}\n}\nMOTION\nFrames: 1\nFrame Time: 0.1\n100 200 300 45\n"
    )
    metres = scale_clip(clip, 0.01)
    np.testing.assert_allclose(metres.values, [[1, 2, 3, 45]])
    np.testing.assert_allclose(metres.skeleton.offsets, [[0.01, 0.02, 0.03]])
    np.testing.assert_allclose(metres.skeleton.end_sites[0], [[0, 0.1, 0]])
    np.testing.assert_allclose(world_positions(metres), world_positions(clip) * 0.01)


# --------------------------------------------------------------------------------------------
# Euler branches

ORDERS = ["XYZ", "XZY", "YXZ", "YZX", "ZXY", "ZYX"]


@pytest.mark.parametrize("order", ORDERS)
def test_alternative_triple_is_the_same_rotation(order):
    euler = np.random.default_rng(1).uniform(-np.pi, np.pi, size=(50, 3))
    a = Rotation.from_euler(order, euler).as_matrix()
    b = Rotation.from_euler(order, euler_alternative(euler, order)).as_matrix()
    np.testing.assert_allclose(a, b, atol=1e-12)


def _sequential_nearest(euler: np.ndarray, order: str) -> np.ndarray:
    """Frame-by-frame loop: each frame is the candidate nearest the previous output."""
    out = [euler[0]]
    for frame in euler[1:]:
        best = None
        for cand in (frame, euler_alternative(frame, order)):
            shifted = out[-1] + (cand - out[-1] + np.pi) % (2 * np.pi) - np.pi
            cost = np.sum((shifted - out[-1]) ** 2)
            if best is None or cost < best[0]:
                best = (cost, shifted)
        out.append(best[1])
    return np.array(out)


@settings(max_examples=40, deadline=None)
@given(st.sampled_from(ORDERS), st.integers(0, 2**31 - 1), st.floats(0.05, 1.5))
def test_continuous_euler_equals_a_frame_by_frame_loop(order, seed, step):
    """Random walks of rotations (steps up to ``step`` rad) converted to principal Euler angles
    then made continuous: same as the plain loop, same rotations, small frame-to-frame steps."""
    rng = np.random.default_rng(seed)
    increments = Rotation.from_rotvec(rng.normal(size=(60, 3)) * step / 2)
    rots = [Rotation.random(random_state=seed)]
    for inc in increments:
        rots.append(inc * rots[-1])
    principal = Rotation.concatenate(rots).as_euler(order)
    cont = euler_continuous(principal, order)
    np.testing.assert_allclose(cont, _sequential_nearest(principal, order), atol=1e-9)
    np.testing.assert_allclose(
        Rotation.from_euler(order, cont).as_matrix(), Rotation.concatenate(rots).as_matrix(),
        atol=1e-9,
    )  # fmt: skip


def test_continuous_euler_removes_wraps_and_branch_flips():
    t = np.linspace(0, 1, 200)
    # Yaw sweeps through ±180°, pitch through 90° and back (a branch flip for as_euler).
    true = np.stack([np.pi * 0.9 + 0.4 * t, 1.6 * np.sin(np.pi * t) + 0.2, 0.3 * t], axis=1)
    principal = Rotation.from_euler("ZYX", true).as_euler("ZYX")
    assert np.abs(np.diff(principal, axis=0)).max() > 3  # the raw curve jumps
    cont = euler_continuous(principal, "ZYX")
    assert np.abs(np.diff(cont, axis=0)).max() < 0.05
    near = euler_nearest(principal, true, "ZYX")
    np.testing.assert_allclose(near, true, atol=1e-9)
