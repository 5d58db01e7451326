"""Forward kinematics and BVH rotations against independent computations: scipy Rotation
objects composed channel by channel in plain Python loops, and hand-written axis matrices."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy.spatial.transform import Rotation

from dancedata.compute.fk import (
    forward_kinematics,
    topological_order,
    transform_points,
    world_transforms,
)
from dancedata.io.bvh import BvhClip, BvhSkeleton, local_translations, read_bvh
from dancedata.ops.bvh_clip import clip_from_rotations, local_rotmats, world_positions


def _reference_fk(clip: BvhClip, frame: int) -> tuple[np.ndarray, list[np.ndarray]]:
    """World positions of one frame and End Site positions, one joint and one channel at a
    time: each rotation channel multiplies in a single-axis scipy rotation (intrinsic), each
    position channel overwrites that axis of the OFFSET."""
    skel = clip.skeleton
    row = iter(clip.values[frame].tolist())
    world: list[tuple[Rotation, np.ndarray]] = []
    for j in range(skel.n_joints):
        rot = Rotation.identity()
        trans = skel.offsets[j].copy()
        for channel in skel.channels[j]:
            value = next(row)
            axis = channel[0].lower()
            if channel.endswith("rotation"):
                rot = rot * Rotation.from_euler(axis, value, degrees=True)
            else:
                trans["xyz".index(axis)] = value
        parent = skel.parents[j]
        if parent < 0:
            world.append((rot, trans))
        else:
            prot, ppos = world[parent]
            world.append((prot * rot, ppos + prot.apply(trans)))
    positions = np.array([pos for _, pos in world])
    ends = [np.array([world[j][1] + world[j][0].apply(e) for e in skel.end_sites[j]]) for j in
            range(skel.n_joints)]  # fmt: skip
    return positions, ends


@pytest.mark.real_data
@pytest.mark.parametrize(
    "name",
    ["01_01.bvh", "AV_8Walk_Meredith_HVHA_Rep1.bvh", "test_freebvh.bvh", "test_mocapbank.bvh",
     "freya_edit.bvh"],
)  # fmt: skip
def test_fk_matches_channel_by_channel_reference(real_data, name):
    clip = read_bvh(real_data / "bvh" / name)
    frames = np.linspace(0, clip.n_frames - 1, 5).astype(int)
    rot, pos = world_transforms(
        clip.skeleton.parents, clip.skeleton.offsets, local_rotmats(clip),
        joint_translations=local_translations(clip),
    )  # fmt: skip
    scale = np.abs(pos).max()
    for f in frames:
        expected, ends = _reference_fk(clip, int(f))
        np.testing.assert_allclose(pos[f], expected, rtol=0, atol=1e-9 * scale)
        for j, e in enumerate(ends):
            if len(e):
                got = transform_points(rot[f : f + 1], pos[f : f + 1], [j] * len(e),
                                       clip.skeleton.end_sites[j])[0]  # fmt: skip
                np.testing.assert_allclose(got, e, rtol=0, atol=1e-9 * scale)
    np.testing.assert_array_equal(world_positions(clip), pos)


@pytest.mark.real_data
def test_six_channel_joints_replace_their_offset(real_data):
    """freya_edit has position channels on every joint that differ slightly from the OFFSETs;
    FK must use the channels (the reference above does) and the difference must be visible."""
    clip = read_bvh(real_data / "bvh" / "freya_edit.bvh")
    trans = local_translations(clip)
    assert not np.allclose(trans[:, 1:], clip.skeleton.offsets[1:])
    with_offsets = forward_kinematics(
        clip.skeleton.parents, clip.skeleton.offsets, local_rotmats(clip),
        root_translation=trans[:, 0],
    )  # fmt: skip
    assert np.abs(with_offsets - world_positions(clip)).max() > 0.01


def _axis_matrix(axis: str, deg: float) -> np.ndarray:
    c, s = np.cos(np.radians(deg)), np.sin(np.radians(deg))
    if axis == "X":
        return np.array([[1, 0, 0], [0, c, -s], [0, s, c]])
    if axis == "Y":
        return np.array([[c, 0, s], [0, 1, 0], [-s, 0, c]])
    return np.array([[c, -s, 0], [s, c, 0], [0, 0, 1]])


ORDERS = ["XYZ", "XZY", "YXZ", "YZX", "ZXY", "ZYX"]


@settings(max_examples=40, deadline=None)
@given(
    st.lists(st.floats(-180, 180), min_size=18, max_size=18),
    st.sampled_from([None, 90.0, -90.0, 89.9999, -90.0001]),
)
def test_channel_orders_against_hand_written_matrices(angles, middle):
    """One joint per channel order; ``middle`` pins the middle angle at gimbal lock."""
    channels = tuple(tuple(f"{a}rotation" for a in order) for order in ORDERS)
    skel = BvhSkeleton(
        names=tuple(ORDERS), parents=(-1, 0, 1, 2, 3, 4), offsets=np.zeros((6, 3)),
        channels=channels,
    )  # fmt: skip
    values = np.array(angles, dtype=np.float64).reshape(6, 3)
    if middle is not None:
        values[:, 1] = middle
    clip = BvhClip(skel, 0.01, values.reshape(1, 18))
    got = local_rotmats(clip)[0]
    for j, order in enumerate(ORDERS):
        a, b, c = values[j]
        expected = _axis_matrix(order[0], a) @ _axis_matrix(order[1], b) @ _axis_matrix(order[2], c)
        np.testing.assert_allclose(got[j], expected, atol=1e-12)


def test_generic_fk_unsorted_parents_and_root_translation():
    rng = np.random.default_rng(3)
    parents = [2, 0, -1, 1, 2]  # root is joint 2
    offsets = rng.normal(size=(5, 3))
    rots = Rotation.random(4 * 5, random_state=4).as_matrix().reshape(4, 5, 3, 3)
    root = rng.normal(size=(4, 3))
    pos = forward_kinematics(parents, offsets, rots, root_translation=root)
    for f in range(4):
        world: dict[int, tuple[np.ndarray, np.ndarray]] = {}
        for j in (2, 0, 4, 1, 3):
            p = parents[j]
            if p < 0:
                world[j] = (rots[f, j], root[f])
            else:
                world[j] = (world[p][0] @ rots[f, j], world[p][1] + world[p][0] @ offsets[j])
        np.testing.assert_allclose(pos[f], [world[j][1] for j in range(5)], atol=1e-12)
    assert topological_order(parents) == [2, 0, 4, 1, 3]
    with pytest.raises(ValueError):
        topological_order([1, 0])


@settings(max_examples=30, deadline=None)
@given(
    st.sampled_from(ORDERS),
    st.integers(0, 2**31 - 1),
    st.sampled_from([None, 90.0, -90.0, 89.999, -89.99999]),
)
def test_rotations_to_channels_and_back_near_gimbal_lock(order, seed, middle):
    """Rotation matrices (scipy) → Euler channels in each order → matrices again: the same
    rotation, including at and near gimbal lock where the angle split is not unique."""
    rots = Rotation.random(20, random_state=seed)
    if middle is not None:
        euler = rots.as_euler(order, degrees=True)
        euler[:, 1] = middle
        rots = Rotation.from_euler(order, euler, degrees=True)
    skel = BvhSkeleton(("j",), (-1,), np.zeros((1, 3)), ((*(f"{a}rotation" for a in order),),))
    clip = clip_from_rotations(skel, 0.01, rots.as_matrix()[:, None])
    back = Rotation.from_matrix(local_rotmats(clip)[:, 0])
    assert np.degrees((back * rots.inv()).magnitude()).max() < 1e-6
