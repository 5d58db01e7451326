"""``dancedata synth aist``: AIST++ scale and statistics (--full), every annotation file in the
real layout, and the vectorised maths behind it checked against scipy and OpenCV."""

from __future__ import annotations

import json
import pickle
from collections import Counter
from pathlib import Path

import cv2
import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from dancedata.compute.camera import project_points, projection_matrix, rodrigues_to_rotmat
from dancedata.io.aist_names import HELD_OUT_MUSIC_IDS, music_bpm
from dancedata.synth.aist import synth_aist
from dancedata.synth.catalog import FPS, demo_plan, full_plan, ignore_list
from dancedata.synth.motion import extrinsic_xyz_to_rotvec

# slow: the full synthetic AIST++ twin (6 sequences, every family) through the pipeline
pytestmark = pytest.mark.slow


def _load(path: Path) -> dict:
    with open(path, "rb") as handle:
        return pickle.load(handle)  # our own synthetic files


@pytest.fixture(scope="module")
def plan():
    return full_plan(0)


def test_full_plan_has_aist_scale(plan):
    assert len(plan) == 1408 and len({s.seq_id for s in plan}) == 1408
    songs = {s.music_id for s in plan}
    assert len(songs) == 60
    assert Counter(m[:3] for m in songs) == {f"m{g[1:]}": 6 for g in {s.genre for s in plan}}
    assert all(s.bpm == music_bpm(s.music_id) for s in plan)
    assert sorted({s.bpm for s in plan}) == [
        80.0, 90.0, 100.0, 110.0, 115.0, 120.0, 125.0, 130.0, 135.0,
    ]  # fmt: skip
    seconds = [s.n_frames / FPS for s in plan]
    assert min(seconds) >= 7.4 - 1e-9 and max(seconds) <= 48.0
    assert min(seconds) < 7.5 and max(seconds) > 47.5  # spans the real range
    for s in plan:
        measures = s.n_frames / (60.0 / s.bpm * 4 * FPS)
        if s.situation == "sBM":
            assert 4.0 <= measures < 4.25, s.seq_id  # ≈4 (stretched to 7.4 s at 135 BPM)
        else:
            assert 15.95 < measures < 16.0, s.seq_id  # ≈16, a frame or two short


def test_full_plan_has_the_real_splits_and_ignore_list(plan):
    crossmodal = Counter(s.split for s in plan)
    assert (crossmodal["train"], crossmodal["val"], crossmodal["test"]) == (980, 20, 20)
    assert Counter(s.pose_split for s in plan) == {"train": 868, "val": 70, "test": 470}
    held_out = set(HELD_OUT_MUSIC_IDS)
    assert {s.music_id for s in plan if s.split in ("val", "test")} == held_out
    assert not {s.music_id for s in plan if s.split == "train"} & held_out
    ignored = set(ignore_list(plan, 0))
    by_split = Counter(s.split for s in plan if s.seq_id in ignored)
    assert len(ignored) == 45 and by_split["train"] == 28
    assert by_split["val"] == by_split["test"] == 0
    assert crossmodal["train"] - by_split["train"] == 952


def test_demo_plan_stays_small_with_splits_in_proportion():
    plan = demo_plan(24, 0)
    assert len(plan) == 24
    assert Counter(s.pose_split for s in plan) == {"train": 15, "test": 8, "val": 1}
    assert len(ignore_list(plan, 0)) == 1


@pytest.fixture(scope="module")
def raw(tmp_path_factory):
    out = tmp_path_factory.mktemp("synth") / "raw"
    synth_aist(out, n_sequences=6, seed=11)
    return out


def test_synth_writes_every_annotation_kind_in_the_aist_layout(raw):
    names = sorted(p.stem for p in (raw / "motions").glob("*.pkl"))
    assert len(names) == 6
    for folder in ("keypoints3d", "keypoints2d"):
        assert sorted(p.stem for p in (raw / folder).glob("*.pkl")) == names
    mapping = dict(
        line.split() for line in (raw / "cameras" / "mapping.txt").read_text().split("\n") if line
    )
    assert sorted(mapping) == names
    for seq_id in names:
        n = _load(raw / "motions" / f"{seq_id}.pkl")["smpl_poses"].shape[0]
        kp3d = _load(raw / "keypoints3d" / f"{seq_id}.pkl")
        assert kp3d["keypoints3d"].shape == kp3d["keypoints3d_optim"].shape == (n, 17, 3)
        kp2d = _load(raw / "keypoints2d" / f"{seq_id}.pkl")
        assert kp2d["keypoints2d"].shape == (9, n, 17, 3)
        assert kp2d["keypoints2d"].dtype == np.float32
        assert kp2d["det_scores"].shape == (9, n)
        assert kp2d["timestamps"].dtype == np.int64
        np.testing.assert_array_equal(np.diff(kp2d["timestamps"][:4]), [16667, 16666, 16667])
        cameras = json.loads((raw / "cameras" / f"{mapping[seq_id]}.json").read_text())
        assert [c["name"] for c in cameras] == [f"c{i:02d}" for i in range(1, 10)]
        for cam in cameras:
            assert cam["size"] == [1920, 1080] and len(cam["distortions"]) == 5
            assert 430 <= np.linalg.norm(_centre_cm(cam)[[0, 2]]) <= 500  # cm, like AIST++
        # keypoints2d is keypoints3d_optim (cm, with cm translation) seen by the cameras.
        projected, _ = cv2.projectPoints(
            kp3d["keypoints3d_optim"].reshape(-1, 3),
            np.array(cameras[4]["rotation"]),
            np.array(cameras[4]["translation"]),
            np.array(cameras[4]["matrix"]),
            np.array(cameras[4]["distortions"]),
        )
        error = np.linalg.norm(
            projected.reshape(n, 17, 2) - kp2d["keypoints2d"][4, :, :, :2], axis=-1
        )
        assert np.nanmedian(error) < 3.0
        inside = kp2d["keypoints2d"][..., 0]
        assert np.nanmin(inside) > 0 and np.nanmax(inside) < 1920
    for scheme in ("crossmodal", "pose"):
        listed = []
        for split in ("train", "val", "test"):
            listed += (raw / "splits" / f"{scheme}_{split}.txt").read_text().split()
        assert (sorted(listed) == names) if scheme == "pose" else set(listed) <= set(names)


def _centre_cm(cam: dict) -> np.ndarray:
    rotation, _ = cv2.Rodrigues(np.array(cam["rotation"]))
    return -rotation.T @ np.array(cam["translation"])


def test_output_bytes_do_not_depend_on_worker_count(raw, tmp_path):
    twin = tmp_path / "twin"
    synth_aist(twin, n_sequences=6, seed=11, workers=2)
    files = sorted(p.relative_to(raw) for p in raw.rglob("*") if p.is_file())
    assert files == sorted(p.relative_to(twin) for p in twin.rglob("*") if p.is_file())
    for rel in files:
        assert (raw / rel).read_bytes() == (twin / rel).read_bytes(), rel


def test_vectorised_euler_to_rotvec_matches_scipy():
    euler = np.random.default_rng(0).uniform(-np.pi, np.pi, (5000, 3))
    euler[:5] = 0.0
    mine = extrinsic_xyz_to_rotvec(euler)
    np.testing.assert_allclose(mine, Rotation.from_euler("xyz", euler).as_rotvec(), atol=1e-12)


def test_rodrigues_matches_scipy_and_opencv():
    rvec = np.random.default_rng(1).normal(0.0, 1.5, (1000, 3))
    rvec[0] = 0.0
    mine = rodrigues_to_rotmat(rvec)
    np.testing.assert_allclose(mine, Rotation.from_rotvec(rvec).as_matrix(), atol=1e-12)
    np.testing.assert_allclose(mine[7], cv2.Rodrigues(rvec[7])[0], atol=1e-12)


def test_project_points_matches_opencv_with_every_distortion_term():
    rng = np.random.default_rng(2)
    n_cams = 4
    intrinsics = np.tile(np.eye(3), (n_cams, 1, 1))
    intrinsics[:, 0, 0], intrinsics[:, 1, 1] = rng.uniform(900, 1600, (2, n_cams))
    intrinsics[:, 0, 2], intrinsics[:, 1, 2] = 960.0, 540.0
    rvec = rng.normal(0.0, 0.3, (n_cams, 3))
    tvec = rng.normal(0.0, 0.2, (n_cams, 3)) + [0.0, 0.0, 4.0]
    distortions = rng.normal(0.0, 0.02, (n_cams, 5))
    points = rng.normal(0.0, 0.6, (50, 17, 3))
    points[3, 4] = np.nan
    mine = project_points(points, intrinsics, rvec, tvec, distortions)
    assert mine.shape == (n_cams, 50, 17, 2)
    assert np.isnan(mine[:, 3, 4]).all()
    finite = points.copy()
    finite[3, 4] = 0.0
    mine = project_points(finite, intrinsics, rvec, tvec, distortions)
    for c in range(n_cams):
        reference, _ = cv2.projectPoints(
            finite.reshape(-1, 3), rvec[c], tvec[c], intrinsics[c], distortions[c]
        )
        np.testing.assert_allclose(mine[c].reshape(-1, 2), reference.reshape(-1, 2), atol=1e-6)
    # Without distortion, P = K [R | t] gives the same pixels, skew included (which
    # cv2.projectPoints ignores: OpenCV's camera model has none).
    intrinsics[:, 0, 1] = rng.uniform(-2, 2, n_cams)
    matrices = projection_matrix(intrinsics, rodrigues_to_rotmat(rvec), tvec)
    homogeneous = np.concatenate([finite.reshape(-1, 3), np.ones((850, 1))], axis=1)
    pinhole = project_points(finite, intrinsics, rvec, tvec, np.zeros((n_cams, 5)))
    for c in range(n_cams):
        pixels = homogeneous @ matrices[c].T
        np.testing.assert_allclose(
            pixels[:, :2] / pixels[:, 2:], pinhole[c].reshape(-1, 2), atol=1e-6
        )
