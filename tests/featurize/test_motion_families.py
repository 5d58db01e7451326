"""Motion families beyond rotations: positions (SMPL model files, BVH offsets), kinematics,
angular and geometric, through ``dancedata featurize``; SMPL model files in every supported
format. References are computed here independently (4x4 transform chains, explicit formulas)."""

from __future__ import annotations

import pickle
from pathlib import Path

import cv2
import numpy as np
import pytest
import scipy.sparse
from scipy.signal import argrelextrema
from scipy.spatial.transform import Rotation

import dancedata
from dancedata.compute.motion_features import geometric_features, kinetic_features
from dancedata.compute.smpl import SMPL_PARENTS
from dancedata.errors import InputError
from dancedata.featurize.featurize import FeaturizeOptions
from dancedata.featurize.featurize import featurize as run_featurize
from dancedata.ingest.aist import AistIngestOptions, ingest_aist
from dancedata.ingest.bvh import BvhIngestOptions, ingest_bvh
from dancedata.ingest.video import VideoIngestOptions, ingest_video
from dancedata.ingest.video.poses import PoseSettings
from dancedata.io.bvh import BvhClip, read_bvh, write_bvh
from dancedata.io.smpl_model import load_smpl_model
from dancedata.store.reader import _VersionReader
from dancedata.synth.aist import synth_aist
from tests.helpers import run_cli

N_VERTICES = 40


# ----------------------------------------------------------------------------- helpers


def smpl_parts(seed: int = 0) -> dict[str, np.ndarray]:
    """A tiny SMPL-like model: 24 joints, 40 vertices, 10 shape components."""
    rng = np.random.default_rng(seed)
    regressor = rng.random((24, N_VERTICES)) * (rng.random((24, N_VERTICES)) < 0.3)
    regressor[:, 0] += 1e-3  # every row non-zero
    regressor /= regressor.sum(axis=1, keepdims=True)
    kintree = np.array([[4294967295, *SMPL_PARENTS[1:]], list(range(24))], dtype=np.int64)
    return {
        "J_regressor": regressor,
        "v_template": rng.normal(size=(N_VERTICES, 3)) * 0.4,
        "shapedirs": rng.normal(size=(N_VERTICES, 3, 10)) * 0.01,
        "kintree_table": kintree,
    }


def write_npz_model(path: Path, seed: int = 0) -> Path:
    np.savez(path, **smpl_parts(seed))
    return path


def reference_smpl_positions(
    parts: dict[str, np.ndarray], axis_angle: np.ndarray, trans: np.ndarray
) -> np.ndarray:
    """Posed SMPL joints by a chain of 4x4 transforms, one joint at a time."""
    rest = parts["J_regressor"] @ parts["v_template"]
    n = axis_angle.shape[0]
    world = np.zeros((n, 24, 4, 4))
    for j, parent in enumerate(SMPL_PARENTS):
        local = np.zeros((n, 4, 4))
        local[:, :3, :3] = Rotation.from_rotvec(axis_angle[:, j]).as_matrix()
        local[:, 3, 3] = 1.0
        if parent < 0:
            local[:, :3, 3] = rest[0] + trans
            world[:, j] = local
        else:
            local[:, :3, 3] = rest[j] - rest[parent]
            world[:, j] = world[:, parent] @ local
    return world[:, :, :3, 3]


def aist_store(tmp_path: Path, sequences: int = 2) -> Path:
    raw, store = tmp_path / "raw", tmp_path / "aist"
    synth_aist(raw, n_sequences=sequences, seed=3, workers=1)
    ingest_aist(store, raw, AistIngestOptions())
    return store


def featurize_cli(store: Path, families: str, *extra: str, check: bool = True):
    return run_cli(
        "featurize", str(store), "--motion-families", families, "--no-audio", "-q", *extra,
        check=check,
    )  # fmt: skip


def featurize(store: Path, families: str) -> None:
    """featurize in this process (the CLI path is covered by featurize_cli)."""
    options = FeaturizeOptions(audio=False, motion_families=families.split(","))
    run_featurize(store, options)


def ingest(store: Path, *paths: Path, **options) -> None:
    ingest_bvh(store, list(paths), BvhIngestOptions(**options))


def one_line_error(proc) -> str:
    assert proc.returncode == 1, proc.stdout + proc.stderr
    lines = [line for line in proc.stderr.splitlines() if line.strip()]
    assert len(lines) == 1 and "Traceback" not in proc.stderr, proc.stderr
    return lines[0]


def sequence_bounds(reader: _VersionReader) -> list[tuple[int, int]]:
    rows = reader.table("sequences").to_pylist()
    return [(r["frame_start"], r["frame_stop"]) for r in rows]


# ----------------------------------------------------------------------------- SMPL files


def test_npz_model_rest_joints_and_offsets(tmp_path: Path) -> None:
    parts = smpl_parts()
    model = load_smpl_model(write_npz_model(tmp_path / "m.npz"))
    rest = parts["J_regressor"] @ parts["v_template"]
    np.testing.assert_allclose(model.rest_joints(), rest, atol=1e-12)
    assert model.parents == SMPL_PARENTS
    offsets = model.joint_offsets()
    for j, p in enumerate(SMPL_PARENTS):
        np.testing.assert_allclose(offsets[j], rest[j] - (rest[p] if p >= 0 else 0), atol=1e-12)
    betas = np.linspace(-1, 1, 10)
    shaped = parts["J_regressor"] @ (parts["v_template"] + parts["shapedirs"] @ betas)
    np.testing.assert_allclose(model.rest_joints(betas), shaped, atol=1e-12)


@pytest.mark.parametrize("protocol", [0, 2, 4])
@pytest.mark.parametrize("sparse", [scipy.sparse.csc_matrix, scipy.sparse.csr_matrix])
def test_pkl_model_with_sparse_regressor(tmp_path: Path, protocol: int, sparse) -> None:
    parts = smpl_parts(1)
    payload = dict(parts, J_regressor=sparse(parts["J_regressor"]), weights=np.ones((3, 24)))
    path = tmp_path / "m.pkl"
    path.write_bytes(pickle.dumps(payload, protocol=protocol))
    model = load_smpl_model(path)
    np.testing.assert_allclose(model.j_regressor, parts["J_regressor"], atol=0)
    np.testing.assert_allclose(model.v_template, parts["v_template"], atol=0)
    assert model.parents == SMPL_PARENTS


def test_unsupported_model_files_say_why(tmp_path: Path) -> None:
    # A pickle naming chumpy (the 2015 SMPL release): GLOBAL chumpy.ch Ch, built by NEWOBJ.
    chumpy = tmp_path / "basicModel.pkl"
    name = b"v_template"
    chumpy.write_bytes(
        b"\x80\x02}X" + len(name).to_bytes(4, "little") + name
        + b"cchumpy.ch\nCh\n)\x81}bs."
    )  # fmt: skip
    with pytest.raises(InputError, match="chumpy") as info:
        load_smpl_model(chumpy)
    assert "npz" in str(info.value) and str(chumpy) in str(info.value)

    evil = tmp_path / "evil.pkl"
    evil.write_bytes(b"\x80\x02cos\nsystem\nX\x04\x00\x00\x00true\x85R.")
    with pytest.raises(InputError, match="os.system"):
        load_smpl_model(evil)

    parts = smpl_parts()
    incomplete = tmp_path / "incomplete.npz"
    np.savez(incomplete, v_template=parts["v_template"])
    with pytest.raises(InputError, match="J_regressor"):
        load_smpl_model(incomplete)

    with pytest.raises(InputError, match="smpl.is.tue.mpg.de"):
        load_smpl_model(tmp_path / "absent.npz")


# ----------------------------------------------------------------------------- positions


@pytest.mark.slow
def test_smpl_positions_through_featurize(tmp_path: Path) -> None:
    store = aist_store(tmp_path)
    model = write_npz_model(tmp_path / "smpl.npz")

    # Without a model: the built-in edge_smpl_offsets skeleton, named in the manifest and attrs
    # (tests/ops/test_smpl_skeleton.py checks its numbers).
    featurize_cli(store, "positions")
    reader = _VersionReader(store)
    config = reader.manifest["config"]["motion_families"]["positions"]
    assert config["skeleton"] == "edge_smpl_offsets" and config["smpl_model"] is None
    assert reader.array("motion/positions").attrs["smpl_skeleton"] == "edge_smpl_offsets"
    builtin_fingerprint = reader.manifest["fingerprint"]

    featurize_cli(store, "positions,angular", "--smpl-model", str(model))
    reader = _VersionReader(store)
    positions = np.asarray(reader.array("motion/positions")[:], dtype=np.float64)
    axis_angle = np.asarray(reader.array("motion/axis_angle")[:], dtype=np.float64)
    trans = np.asarray(reader.array("motion/trans")[:], dtype=np.float64)
    expected = reference_smpl_positions(smpl_parts(), axis_angle, trans)
    assert np.abs(positions - expected).max() < 2e-6  # float32 storage of metres
    config = reader.manifest["config"]["motion_families"]["positions"]
    assert config["smpl_model"]["file"] == "smpl.npz" and len(config["smpl_model"]["sha256"]) == 64
    assert config["skeleton"] == f"sha256:{config['smpl_model']['sha256']}"  # the model wins
    assert reader.manifest["fingerprint"] != builtin_fingerprint

    # Positions now exist: kinematics and geometric run on this version's output.
    featurize(store, "kinematics,geometric")
    reader = _VersionReader(store)
    assert reader.manifest["counts"]["motion_absent"] == {}
    geometric = np.asarray(reader.array("motion/geometric_features")[:])
    kinetic = np.asarray(reader.array("motion/kinetic_features")[:])
    fps = reader.group_attrs("motion")["fps"]
    for start, stop in sequence_bounds(reader):
        seq = positions[start:stop]
        want = np.broadcast_to(geometric_features(seq), (stop - start, 32))
        np.testing.assert_allclose(geometric[start:stop], want, atol=1e-7)
        want = kinetic_features(seq, fps, mode="parity")
        assert kinetic.shape[1] == 72
        np.testing.assert_allclose(kinetic[start:stop], np.broadcast_to(want, (stop - start, 72)),
                                   rtol=1e-4, atol=1e-5)  # fmt: skip
    assert run_cli("validate", str(store)).returncode == 0


@pytest.mark.real_data
def test_positions_family_refuses_rigs_with_joint_translations(real_data: Path, tmp_path) -> None:
    store = tmp_path / "freya"
    ingest(store, real_data / "bvh" / "freya_edit.bvh", fps=25.0)
    with pytest.raises(InputError, match="already stored"):
        featurize(store, "positions")


@pytest.mark.real_data
def test_bvh_positions_family_rebuilds_ingest_positions(real_data: Path, tmp_path) -> None:
    store = tmp_path / "mocap"
    ingest(store, real_data / "bvh" / "test_mocapbank.bvh")
    before = np.asarray(_VersionReader(store).array("motion/positions")[:])
    featurize(store, "positions")
    after = np.asarray(_VersionReader(store).array("motion/positions")[:])
    assert np.abs(after - before).max() < 5e-6  # FK of float32 axis-angle vs of the channels


# ----------------------------------------------------------------------------- kinematics


def two_sequence_bvh_store(real_data: Path, tmp_path: Path) -> Path:
    """test_mocapbank (455 frames) and its first 120 frames under another name."""
    source = real_data / "bvh" / "test_mocapbank.bvh"
    clip = read_bvh(source)
    short = tmp_path / "short.bvh"
    write_bvh(BvhClip(clip.skeleton, clip.frame_time_s, clip.values[:120]), short)
    store = tmp_path / "two"
    ingest(store, source, short)
    return store


def hamilton(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    w1, x1, y1, z1 = np.moveaxis(a, -1, 0)
    w2, x2, y2, z2 = np.moveaxis(b, -1, 0)
    return np.stack(
        [
            w1 * w2 - x1 * x2 - y1 * y2 - z1 * z2,
            w1 * x2 + x1 * w2 + y1 * z2 - z1 * y2,
            w1 * y2 - x1 * z2 + y1 * w2 + z1 * x2,
            w1 * z2 + x1 * y2 - y1 * x2 + z1 * w2,
        ],
        axis=-1,
    )


@pytest.mark.slow
@pytest.mark.real_data
def test_kinematics_and_angular_on_a_bvh_store(real_data: Path, tmp_path: Path) -> None:
    store = two_sequence_bvh_store(real_data, tmp_path)
    line = one_line_error(featurize_cli(store, "rotations,kinematics,geometric", check=False))
    assert "SMPL-24" in line
    featurize(store, "rotations,kinematics,angular")
    reader = _VersionReader(store)
    fps = reader.group_attrs("motion")["fps"]
    assert fps == 30.0
    p = np.asarray(reader.array("motion/positions")[:], dtype=np.float64)
    arrays = {
        name: np.asarray(reader.array(f"motion/{name}")[:], dtype=np.float64)
        for name in ("velocity", "acceleration", "jerk", "angular_velocity", "weight_effort",
                     "motion_beats_mint", "motion_beats_bailando", "kinetic_features_corrected")
    }  # fmt: skip
    axis_angle = np.asarray(reader.array("motion/axis_angle")[:], dtype=np.float64)
    for start, stop in sequence_bounds(reader):
        seq = p[start:stop]
        n = stop - start
        # Derivatives: forward differences at the store rate, last rows repeated.
        v = (seq[1:] - seq[:-1]) * fps
        a = (seq[2:] - 2 * seq[1:-1] + seq[:-2]) * fps**2
        j = (seq[3:] - 3 * seq[2:-1] + 3 * seq[1:-2] - seq[:-3]) * fps**3
        for name, want, k in (("velocity", v, 1), ("acceleration", a, 2), ("jerk", j, 3)):
            got = arrays[name][start:stop]
            scale = np.abs(want).max()
            assert np.abs(got[: n - k] - want).max() < 1e-5 * scale, name
            assert (got[n - k :] == got[n - k - 1]).all(), name  # never crosses into the next
        # mint beats: strict minima over ±10 frames of the summed displacement arriving at t.
        env = np.zeros(n)
        env[1:] = np.linalg.norm(seq[1:] - seq[:-1], axis=-1).sum(axis=1)
        want_beats = argrelextrema(env, np.less, order=10)[0]
        assert np.flatnonzero(arrays["motion_beats_mint"][start:stop]).tolist() == (
            want_beats.tolist()
        )
        assert arrays["motion_beats_bailando"][start:stop].sum() > 0
        corrected = kinetic_features(seq, fps, mode="corrected")
        np.testing.assert_allclose(arrays["kinetic_features_corrected"][start], corrected,
                                   rtol=1e-4, atol=1e-6)  # fmt: skip
        # Angular velocity: vector part of 2 (q[t+1] - q[t]) fps conj(q[t]), signs continuous.
        xyzw = Rotation.from_rotvec(axis_angle[start:stop].reshape(-1, 3)).as_quat()
        q = xyzw[:, [3, 0, 1, 2]].reshape(n, -1, 4)
        for t in range(1, n):
            q[t] *= np.where(np.sum(q[t] * q[t - 1], axis=-1, keepdims=True) < 0, -1.0, 1.0)
        conj = q[:-1] * np.array([1.0, -1.0, -1.0, -1.0])
        omega = 2.0 * hamilton((q[1:] - q[:-1]) * fps, conj)[..., 1:]
        got = arrays["angular_velocity"][start:stop]
        assert np.abs(got[:-1] - omega).max() < 1e-3 * np.abs(omega).max()
        effort = np.linalg.norm(omega, axis=-1).sum(axis=1)
        np.testing.assert_allclose(arrays["weight_effort"][start : stop - 1], effort, rtol=1e-3)
    assert run_cli("validate", str(store)).returncode == 0


def test_video_store_with_positions_only(tmp_path: Path) -> None:
    fps, n = 25.0, 30
    video = tmp_path / "clip.mp4"
    writer = cv2.VideoWriter(str(video), cv2.VideoWriter_fourcc(*"mp4v"), fps, (64, 48))
    for i in range(n):
        writer.write(np.full((48, 64, 3), i, np.uint8))
    writer.release()
    t = np.arange(n) / fps
    rng = np.random.default_rng(2)
    base = rng.normal(size=(18, 3))
    positions = base[None] + np.sin(2 * np.pi * 1.5 * t)[:, None, None] * rng.normal(size=(18, 3))
    csv = tmp_path / "clip.csv"
    csv.write_text("\n".join(",".join(f"{v:.7f}" for v in row.ravel()) for row in positions))
    store = tmp_path / "video"
    video_options = VideoIngestOptions(
        joints_csv=csv, no_music=True, settings=PoseSettings(skeleton="coco18")
    )
    ingest_video(store, [video], video_options)

    featurize(store, "rotations,kinematics,angular")
    reader = _VersionReader(store)
    absent = reader.manifest["counts"]["motion_absent"]
    assert set(absent) == {"rotations", "angular"} and "axis_angle" in absent["angular"]
    velocity = np.asarray(reader.array("motion/velocity")[:])
    stored = np.asarray(reader.array("motion/positions")[:], dtype=np.float64)
    want = (stored[1:] - stored[:-1]) * fps
    np.testing.assert_allclose(velocity[:-1], want, rtol=1e-5, atol=1e-4)
    assert reader.array("motion/kinetic_features").shape == (n, 54)
    assert not reader.has_array("motion/angular_velocity")
    ds = dancedata.open_store(store)
    assert ds.motion("clip", "velocity").shape == (n, 18, 3)
