"""Joint rotations from joint positions (issue 14, item 5): bone-direction IK.

Pure layer: synthetic positions made by forward kinematics from known rotations on a known
skeleton → IK → FK reproduces every joint within 1e-6; rotations match where the twist is
determined; the best-fit rotation equals scipy's ``Rotation.align_vectors``. End to end through
the CLI: a joints CSV in the on-disk format → ``ingest video`` (no video, ``--fps``) →
``featurize --motion-families rotations_from_positions`` → ``export bvh`` → dancedata's BVH
reader → FK → within 1 mm of the CSV (rigid input: 0.0005 mm). Real data: AIST++'s
triangulated 3-d keypoints (a real, non-rigid pose estimate) go the same way; a rigid skeleton
cannot follow them to 1 mm (median 31 mm for joints with a child), and the exported BVH
reproduces exactly the residual the IK recorded in motion/ik_residual.
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from dancedata.compute.fk import forward_kinematics
from dancedata.compute.ik import (
    IK_METHOD,
    best_fit_rotation,
    fk_residual,
    rest_skeleton,
    shortest_arc,
    solve_rotations,
)
from dancedata.errors import InputError
from dancedata.featurize.families.motion import MotionBatch, MotionSettings
from dancedata.featurize.families.motion_ik import RotationsFromPositionsFamily
from dancedata.io.bvh import read_bvh
from dancedata.io.openpose import BODY_25, COCO_18
from dancedata.ops.bvh_clip import world_positions
from dancedata.store.reader import _VersionReader
from tests.helpers import run_cli

PARENTS = list(BODY_25.parents)
J = len(PARENTS)
ROOT = PARENTS.index(-1)
CHILDREN = [[c for c, p in enumerate(PARENTS) if p == j] for j in range(J)]
HAS_CHILD = np.array([bool(c) for c in CHILDREN])


def known_skeleton(seed: int = 0) -> np.ndarray:
    """Random BODY_25 rest offsets (metres), root zero."""
    offsets = np.random.default_rng(seed).normal(size=(J, 3)) * 0.15
    offsets[ROOT] = 0.0
    return offsets


def random_rotations(n_frames: int, seed: int) -> np.ndarray:
    return Rotation.random(n_frames * J, random_state=seed).as_matrix().reshape(n_frames, J, 3, 3)


def twist_free_rotations(n_frames: int, offsets: np.ndarray, seed: int) -> np.ndarray:
    """Random local rotations whose twist IK can determine: any rotation for joints with
    several children, a swing (axis perpendicular to the child's bone) for one child, identity
    for leaves."""
    rng = np.random.default_rng(seed)
    rot = random_rotations(n_frames, seed)
    for j in range(J):
        if len(CHILDREN[j]) == 1:
            bone = offsets[CHILDREN[j][0]] / np.linalg.norm(offsets[CHILDREN[j][0]])
            axis = np.cross(bone, rng.normal(size=(n_frames, 3)))
            axis /= np.linalg.norm(axis, axis=1, keepdims=True)
            angle = rng.uniform(-3.0, 3.0, size=(n_frames, 1))
            rot[:, j] = Rotation.from_rotvec(axis * angle).as_matrix()
        elif not CHILDREN[j]:
            rot[:, j] = np.eye(3)
    return rot


# ----------------------------------------------------------------------------- pure layer


def test_best_fit_rotation_equals_scipy_align_vectors() -> None:
    rng = np.random.default_rng(1)
    rest = rng.normal(size=(4, 3))
    observed = rng.normal(size=(50, 4, 3))
    weights = rng.uniform(0.2, 2.0, size=(50, 4))
    ours = best_fit_rotation(rest, observed, weights)
    ref = np.stack(
        [
            Rotation.align_vectors(o, rest, weights=w)[0].as_matrix()
            for o, w in zip(observed, weights, strict=True)
        ]
    )
    np.testing.assert_allclose(ours, ref, atol=1e-10)
    np.testing.assert_allclose(np.linalg.det(ours), 1.0, atol=1e-12)  # never a reflection


def test_shortest_arc_maps_a_to_b_without_twist_including_half_turns() -> None:
    rng = np.random.default_rng(2)
    a = rng.normal(size=(200, 3))
    a /= np.linalg.norm(a, axis=1, keepdims=True)
    b = rng.normal(size=(200, 3))
    b /= np.linalg.norm(b, axis=1, keepdims=True)
    b[:5] = -a[:5]  # opposite: a half turn
    b[5:8] = a[5:8]  # equal: identity
    rot = shortest_arc(a, b)
    np.testing.assert_allclose(np.einsum("fij,fj->fi", rot, a), b, atol=1e-12)
    np.testing.assert_allclose(
        rot @ np.swapaxes(rot, 1, 2), np.broadcast_to(np.eye(3), rot.shape), atol=1e-12
    )
    np.testing.assert_allclose(np.linalg.det(rot), 1.0, atol=1e-12)
    np.testing.assert_allclose(rot[5:8], np.broadcast_to(np.eye(3), (3, 3, 3)), atol=1e-12)
    axis = Rotation.from_matrix(rot[8:]).as_rotvec()  # swing only: the axis is a × b
    np.testing.assert_allclose(np.einsum("fi,fi->f", axis, a[8:]), 0.0, atol=1e-9)
    angle = np.arccos(np.clip(np.einsum("fi,fi->f", a[8:], b[8:]), -1, 1))  # the shortest arc
    np.testing.assert_allclose(np.linalg.norm(axis, axis=1), angle, atol=1e-9)


def test_rest_skeleton_median_lengths_and_first_observed_direction() -> None:
    offsets = known_skeleton()
    rot = random_rotations(41, seed=3)
    positions = forward_kinematics(PARENTS, offsets, rot, np.zeros((41, 3)))
    scale = np.random.default_rng(4).uniform(0.9, 1.1, size=(41, 1, 1))
    noisy = positions.copy()
    noisy[:, 4] = positions[:, 3] + scale[:, 0] * (positions[:, 4] - positions[:, 3])  # RWrist
    noisy[:2, 7] = np.nan  # LWrist unknown in frames 0-1: direction from frame 2
    rest = rest_skeleton(noisy, PARENTS)
    length = np.median(np.linalg.norm(noisy[:, 4] - noisy[:, 3], axis=1))
    np.testing.assert_allclose(np.linalg.norm(rest[4]), length, rtol=1e-12)
    first_dir = (noisy[0, 4] - noisy[0, 3]) / np.linalg.norm(noisy[0, 4] - noisy[0, 3])
    np.testing.assert_allclose(rest[4] / length, first_dir, atol=1e-12)
    d2 = noisy[2, 7] - noisy[2, 6]
    np.testing.assert_allclose(
        rest[7], d2 / np.linalg.norm(d2) * np.linalg.norm(offsets[7]), atol=1e-12
    )
    assert (rest[ROOT] == 0).all()
    gone = noisy.copy()
    gone[:, 17] = np.nan
    with pytest.raises(ValueError, match="never observed"):
        rest_skeleton(gone, PARENTS)


def test_fk_ik_fk_reproduces_every_joint_from_random_rotations() -> None:
    offsets = known_skeleton()
    rot = random_rotations(300, seed=5)  # full rotations: twist of one-child joints is lost
    trans = np.random.default_rng(6).normal(size=(300, 3))
    positions = forward_kinematics(PARENTS, offsets, rot, trans)
    rest = rest_skeleton(positions, PARENTS)  # measured from the data, first-frame directions
    np.testing.assert_allclose(
        np.linalg.norm(rest, axis=1), np.linalg.norm(offsets, axis=1), atol=1e-12
    )
    solution = solve_rotations(positions, PARENTS, rest)
    refk = forward_kinematics(PARENTS, rest, solution.local_rotations, solution.root_translation)
    error = np.linalg.norm(refk - positions, axis=-1)
    assert error[:, HAS_CHILD].max() < 1e-6  # the bar: every joint that has a child
    assert error.max() < 1e-6  # and the leaves too, for a rigid skeleton
    np.testing.assert_allclose(
        solution.local_rotations[0], np.broadcast_to(np.eye(3), (J, 3, 3)), atol=1e-9
    )
    codes = {j: 2 if len(c) > 1 else 1 if c else 0 for j, c in enumerate(CHILDREN)}
    assert (solution.solved == np.array([codes[j] for j in range(J)])).all()


def test_rotations_recovered_where_the_twist_is_determined() -> None:
    offsets = known_skeleton(7)
    rot = twist_free_rotations(200, offsets, seed=8)
    rot[0] = np.eye(3)  # first frame = rest pose, so the measured rest skeleton is the known one
    positions = forward_kinematics(PARENTS, offsets, rot, np.zeros((200, 3)))
    rest = rest_skeleton(positions, PARENTS)
    np.testing.assert_allclose(rest, offsets, atol=1e-12)
    solution = solve_rotations(positions, PARENTS, rest)
    np.testing.assert_allclose(solution.local_rotations, rot, atol=1e-8)
    # With full random rotations, joints with several children still recover theirs exactly
    # (world rotation fixed by the children); one-child joints only up to their twist.
    full = random_rotations(50, seed=9)
    full[0] = np.eye(3)
    positions = forward_kinematics(PARENTS, offsets, full, np.zeros((50, 3)))
    solved = solve_rotations(positions, PARENTS, offsets)
    many = [j for j in range(J) if len(CHILDREN[j]) > 1 and PARENTS[j] < 0]
    np.testing.assert_allclose(solved.local_rotations[:, many], full[:, many], atol=1e-8)


def test_missing_children_fall_back_and_rigid_fk_stays_exact() -> None:
    offsets = known_skeleton(10)
    rot = random_rotations(30, seed=11)
    positions = forward_kinematics(PARENTS, offsets, rot, np.zeros((30, 3)))
    holes = positions.copy()
    holes[5, 2] = np.nan  # Neck keeps Nose and LShoulder: still a best fit
    holes[6, [2, 5]] = np.nan  # only Nose left: shortest arc
    holes[7, [0, 2, 5]] = np.nan  # no child known: identity
    solution = solve_rotations(holes, PARENTS, offsets)
    assert solution.solved[5, 1] == 2 and solution.solved[6, 1] == 1 and solution.solved[7, 1] == 0
    assert np.isfinite(solution.local_rotations).all()
    error = fk_residual(
        holes, PARENTS, offsets, solution.local_rotations, solution.root_translation
    )
    # rigid data: the remaining two children fix the Neck, so every joint outside the missing
    # RShoulder's own subtree (RElbow, RWrist: no observed start point) sits exactly
    outside = [j for j in range(J) if j not in (2, 3, 4)]
    assert np.nanmax(error[5, outside]) < 1e-9
    assert np.isnan(error[5, 2]) and np.isfinite(error[5, 3])


def test_family_refuses_rotation_stores_and_flat_skeletons() -> None:
    family = RotationsFromPositionsFamily()
    batch = MotionBatch(
        arrays={"positions": np.zeros((4, 3, 3))},
        bounds=np.array([[0, 4]]),
        attrs={
            "skeleton": {
                "name": "bvh",
                "joints": ["a", "b", "c"],
                "parents": [-1, 0, 1],
                "offsets": np.zeros((3, 3)).tolist(),
            }
        },
    )
    with pytest.raises(InputError, match="source rotations"):
        family.compute(batch, MotionSettings())
    flat = MotionBatch(
        arrays=batch.arrays,
        bounds=batch.bounds,
        attrs={"skeleton": {"name": "custom", "joints": ["a", "b", "c"], "parents": [-1, -1, -1]}},
    )
    with pytest.raises(InputError, match="no bone structure"):
        family.compute(flat, MotionSettings())


# ----------------------------------------------------------------------------- end to end


def write_joints_csv(path: Path, names, positions: np.ndarray, scale: float = 1.0) -> Path:
    """A pose lifter's CSV as ``ingest video --joints-csv`` reads it: a frame column, then
    ``<joint>_x, <joint>_y, <joint>_z`` per joint, six decimals."""
    header = ["frame"] + [f"{n}_{a}" for n in names for a in "xyz"]
    lines = [",".join(header)]
    for i, row in enumerate(positions * scale):
        lines.append(",".join([str(i)] + [f"{v:.6f}" for v in row.ravel()]))
    path.write_text("\n".join(lines) + "\n")
    return path


def cli_json(*args: str) -> dict:
    proc = run_cli(*args, "--json")
    return json.loads(proc.stdout[proc.stdout.index("{") :])


def csv_to_bvh_positions(
    tmp_path: Path, csv: Path, fps: str, units: str, names, max_gap: str = "0"
) -> tuple[np.ndarray, Path]:
    """joints CSV → ingest video (no video) → featurize IK → export bvh → read → FK (metres),
    columns in ``names`` order; and the store."""
    store, out = tmp_path / "store", tmp_path / "out.bvh"
    cli_json(
        "ingest",
        "video",
        "--joints-csv",
        str(csv),
        "--fps",
        fps,
        "--units",
        units,
        "--max-gap",
        max_gap,
        "--store",
        str(store),
        "-q",
    )
    refused = run_cli("export", "bvh", str(store), csv.stem, str(out), check=False)
    assert refused.returncode == 1 and "rotations_from_positions" in refused.stderr
    summary = cli_json(
        "featurize", str(store), "--motion-families", "rotations_from_positions", "--no-audio", "-q"
    )
    assert summary["version"] == "v2"
    exported = cli_json("export", "bvh", str(store), csv.stem, str(out), "--units", "cm")
    assert "ik_rest_offsets" in exported["offsets_from"]
    clip = read_bvh(out)
    order = [clip.skeleton.names.index(n) for n in names]
    return world_positions(clip)[:, order] / 100.0, store


@pytest.mark.slow
def test_joints_csv_to_bvh_through_the_cli_within_a_millimetre(tmp_path: Path) -> None:
    offsets = known_skeleton(12)
    rot = random_rotations(90, seed=13)
    trans = np.cumsum(np.random.default_rng(14).normal(scale=0.01, size=(90, 3)), axis=0)
    positions = forward_kinematics(PARENTS, offsets, rot, trans + [0.0, 0.9, 3.0])
    csv = write_joints_csv(tmp_path / "dancer.csv", BODY_25.joints, positions, scale=1000.0)  # mm
    fk, store = csv_to_bvh_positions(tmp_path, csv, "30", "mm", BODY_25.joints)
    error = np.linalg.norm(fk - positions, axis=-1)
    print(f"synthetic BODY_25 CSV → BVH → FK: max error {error.max() * 1e3:.4f} mm")
    assert error[:, HAS_CHILD].max() < 1e-3  # the bar: within 1 mm for every joint with a child
    assert error.max() < 1e-3
    reader = _VersionReader(store)
    axis_angle = reader.array("motion/axis_angle")
    assert axis_angle.attrs["method"] == IK_METHOD and axis_angle.attrs["units"] == "rad"
    assert reader.array("motion/trans").attrs["method"]["name"] == "bone_direction_ik"
    config = reader.manifest["config"]["motion_families"]["rotations_from_positions"]
    assert config["method"] == IK_METHOD  # the method is in the manifest too
    assert np.nanmax(reader.array("motion/ik_residual")[:]) < 1e-5
    assert run_cli("validate", str(store), check=False).returncode == 0


@pytest.mark.slow
@pytest.mark.real_data
def test_real_aist_keypoints_to_bvh_reproduce_the_recorded_residual(
    real_data: Path, tmp_path: Path
) -> None:
    """AIST++ keypoints3d (real, triangulated from 9 views, COCO-17, bone lengths vary) with a
    Neck added at the shoulders' midpoint (OpenPose COCO-18): the BVH's FK equals the input up
    to the residual the IK recorded (what a rigid skeleton cannot follow), joint for joint."""
    from dancedata.io.aist_keypoints import read_keypoints3d

    kp = read_keypoints3d(real_data / "aist/keypoints3d/gBR_sBM_cAll_d04_mBR2_ch08.pkl").keypoints3d
    coco17 = np.asarray(kp, np.float64)[:240]
    neck = 0.5 * (coco17[:, 5] + coco17[:, 6])
    # COCO-17 (nose, leye, reye, lear, rear, lsho, rsho, lelb, relb, lwri, rwri, lhip, rhip,
    # lknee, rknee, lank, rank) → OpenPose COCO-18 order
    take = {
        "Nose": 0,
        "RShoulder": 6,
        "RElbow": 8,
        "RWrist": 10,
        "LShoulder": 5,
        "LElbow": 7,
        "LWrist": 9,
        "RHip": 12,
        "RKnee": 14,
        "RAnkle": 16,
        "LHip": 11,
        "LKnee": 13,
        "LAnkle": 15,
        "REye": 2,
        "LEye": 1,
        "REar": 4,
        "LEar": 3,
    }
    positions = np.stack([neck if n == "Neck" else coco17[:, take[n]] for n in COCO_18.joints], 1)
    csv = write_joints_csv(tmp_path / "gBR.csv", COCO_18.joints, positions)
    fk, store = csv_to_bvh_positions(tmp_path, csv, "60", "m", COCO_18.joints, max_gap="3")
    reader = _VersionReader(store)
    stored = np.asarray(reader.array("motion/positions")[:], np.float64)  # knee gaps filled
    residual = np.asarray(reader.array("motion/ik_residual")[:], np.float64)
    error = np.linalg.norm(fk - stored, axis=-1)
    has_child = np.array([any(p == j for p in COCO_18.parents) for j in range(len(COCO_18.joints))])
    print(
        f"AIST++ keypoints3d → BVH → FK: max error {np.nanmax(error) * 1e3:.2f} mm (joints with "
        f"a child {np.nanmax(error[:, has_child]) * 1e3:.2f} mm, median "
        f"{np.nanmedian(error[:, has_child]) * 1e3:.2f} mm), recorded IK residual max "
        f"{np.nanmax(residual) * 1e3:.2f} mm; {int(np.isnan(positions).any(-1).sum())} joint "
        "observations missing"
    )
    assert np.isnan(positions).any()  # AIST++ misses knees in a few frames
    assert np.abs(stored - positions)[np.isfinite(positions)].max() < 1e-6
    assert np.isfinite(fk).all()
    np.testing.assert_allclose(error, residual, atol=2e-5)  # export adds < 0.02 mm
    # The root sits exactly; the rest move by what a rigid skeleton cannot follow: bone lengths
    # that vary (AIST++ raw keypoints: 4-70 mm standard deviation) and a torso that bends (the
    # Neck's five children, hips included, get one best-fit rotation).
    assert error[:, COCO_18.parents.index(-1)].max() < 1e-5
    assert 5e-3 < np.nanmedian(error[:, has_child]) < 0.1  # real data: not rigid, not wild
