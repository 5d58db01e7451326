"""The built-in SMPL-24 rest skeleton (``edge_smpl_offsets``): joint positions without a model file.

The reference is an independent forward kinematics written here: every joint's position summed
along its chain from the root, each bone turned by the product of its ancestors' rotations, with
``scipy.spatial.transform.Rotation`` (no dancedata rotation or FK code). It is run on the real
AIST++ motions (the release's pickles, read with plain ``pickle``; translation divided by
``smpl_scaling`` as AIST++ does).
"""

from __future__ import annotations

import pickle
from pathlib import Path

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from dancedata.compute.smpl import SMPL_PARENTS
from dancedata.compute.smpl_skeleton import (
    EDGE_SMPL_OFFSETS_M,
    EDGE_SMPL_SKELETON,
    SMPL24_PARENTS,
)
from dancedata.errors import InputError
from dancedata.ops.smpl_skeletons import skeleton_name, smpl_skeleton
from dancedata.store.reader import _VersionReader
from tests.helpers import run_cli


def chain(joint: int) -> list[int]:
    """Root first, ``joint`` last."""
    out = [joint]
    while SMPL_PARENTS[out[-1]] >= 0:
        out.append(SMPL_PARENTS[out[-1]])
    return out[::-1]


def brute_force_positions(axis_angle: np.ndarray, trans: np.ndarray) -> np.ndarray:
    """(F, 24, 3): x_j = trans + sum over the bones k on the chain to j of
    (R_root ... R_parent(k)) offset_k, each product composed from scratch with scipy."""
    n = len(axis_angle)
    local = [Rotation.from_rotvec(axis_angle[:, j]) for j in range(24)]
    out = np.empty((n, 24, 3))
    for j in range(24):
        path = chain(j)
        x = np.array(trans, dtype=np.float64)
        for depth in range(1, len(path)):
            turn = local[path[0]]
            for ancestor in path[1:depth]:
                turn = turn * local[ancestor]
            x = x + turn.apply(np.array(EDGE_SMPL_OFFSETS_M[path[depth]]))
        out[:, j] = x
    return out


def real_motions(real_data: Path) -> list[tuple[str, np.ndarray, np.ndarray]]:
    motions = []
    for path in sorted((real_data / "aist" / "motions").glob("*.pkl")):
        with path.open("rb") as handle:
            data = pickle.load(handle)  # the AIST++ release files
        poses = np.asarray(data["smpl_poses"], dtype=np.float64).reshape(-1, 24, 3)
        trans = np.asarray(data["smpl_trans"], dtype=np.float64) / float(data["smpl_scaling"][0])
        motions.append((path.stem, poses, trans))
    assert len(motions) == 4
    return motions


def test_table_is_smpl24_with_the_root_at_the_translation() -> None:
    assert SMPL24_PARENTS == SMPL_PARENTS and EDGE_SMPL_SKELETON.parents == SMPL_PARENTS
    assert EDGE_SMPL_OFFSETS_M.shape == (24, 3) and not EDGE_SMPL_OFFSETS_M.flags.writeable
    assert np.all(EDGE_SMPL_OFFSETS_M[0] == 0)
    # Left/right bones mirror each other to within 1.5 cm (x flips sign): a typo in the table
    # would break this.
    for left, right in ((1, 2), (4, 5), (7, 8), (10, 11), (13, 14), (16, 17), (18, 19), (20, 21)):
        mirrored = EDGE_SMPL_OFFSETS_M[right] * [-1, 1, 1]
        assert np.abs(EDGE_SMPL_OFFSETS_M[left] - mirrored).max() < 0.015, (left, right)
    with pytest.raises(ValueError, match="betas fixed at zero"):
        EDGE_SMPL_SKELETON.joint_offsets(np.ones(10))
    rest = smpl_skeleton(None)
    assert rest.name == skeleton_name(None) == "edge_smpl_offsets"
    assert rest.record() == {
        "skeleton": "edge_smpl_offsets",
        "root": "trans",
        "betas": "zeros",
        "units": "m",
        "smpl_model": None,
    }


def test_a_model_file_wins_and_is_named_by_its_sha256(tmp_path: Path) -> None:
    import hashlib

    from tests.featurize.test_motion_families import write_npz_model

    model = write_npz_model(tmp_path / "smpl.npz")
    chosen = smpl_skeleton(model)
    sha = hashlib.sha256(model.read_bytes()).hexdigest()
    assert chosen.name == skeleton_name(model) == f"sha256:{sha}"
    assert chosen.record()["smpl_model"] == {"file": "smpl.npz", "sha256": sha}
    assert chosen.record()["root"] == "J0 + trans"
    with pytest.raises(InputError, match="not found"):
        skeleton_name(tmp_path / "absent.npz")


@pytest.mark.real_data
def test_positions_equal_an_independent_fk_on_real_aist_motions(real_data: Path) -> None:
    rest = smpl_skeleton(None)
    worst = 0.0
    for name, poses, trans in real_motions(real_data):
        got = rest.positions(poses, trans)
        want = brute_force_positions(poses, trans)
        np.testing.assert_array_equal(got[:, 0], trans)  # the root sits at the translation
        worst = max(worst, float(np.abs(got - want).max()))
        assert np.abs(got - want).max() <= 1e-9, name  # both float64
        bones = np.linalg.norm(got[:, 1:] - got[:, list(SMPL_PARENTS[1:])], axis=-1)
        np.testing.assert_allclose(bones, np.broadcast_to(
            np.linalg.norm(EDGE_SMPL_OFFSETS_M[1:], axis=1), bones.shape), atol=1e-9)  # fmt: skip
    assert worst < 1e-9


@pytest.mark.slow
@pytest.mark.real_data
def test_featurize_positions_without_a_model_on_a_real_aist_store(
    real_data: Path, tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """``featurize --motion-families positions`` on a store of the real motions, no model file:
    stored float32 positions within 1e-5 m of the independent FK; the skeleton is recorded."""
    monkeypatch.delenv("DANCEDATA_SMPL_MODEL", raising=False)
    store = tmp_path / "store"
    run_cli("ingest", "aist", str(real_data / "aist"), "--store", str(store),
            "--allow-missing-music", "-q")  # fmt: skip
    run_cli("featurize", str(store), "--motion-families", "positions", "--no-audio", "-q")
    reader = _VersionReader(store)
    config = reader.manifest["config"]["motion_families"]["positions"]
    assert config["skeleton"] == "edge_smpl_offsets" and config["smpl_model"] is None
    positions = reader.array("motion/positions")
    assert positions.attrs["smpl_skeleton"] == "edge_smpl_offsets"
    rows = {r["seq_id"]: r for r in reader.table("sequences").to_pylist()}
    worst = 0.0
    for name, poses, trans in real_motions(real_data):
        row = rows[name]
        stored = np.asarray(positions[row["frame_start"] : row["frame_stop"]], dtype=np.float64)
        # the store keeps float32 rotations and translation; the reference starts from those
        aa32 = poses.astype(np.float32).astype(np.float64)
        tr32 = trans.astype(np.float32).astype(np.float64)
        worst = max(worst, float(np.abs(stored - brute_force_positions(aa32, tr32)).max()))
    print(f"featurize positions vs independent FK on real AIST++: max {worst:.3g} m")
    assert worst <= 1e-5, worst


# ------------------------------------------------------------------ evaluate without a model


@pytest.fixture(scope="module")
def synthetic_store(tmp_path_factory: pytest.TempPathFactory) -> Path:
    root = tmp_path_factory.mktemp("skeleton-evaluate")
    run_cli("synth", "aist", str(root / "raw"), "--sequences", "4", "--seed", "0", "-q")
    run_cli("ingest", "aist", str(root / "raw"), "--store", str(root / "st"), "-q")
    return root / "st"


@pytest.mark.slow
def test_evaluate_without_a_model_poses_ground_truth_about_the_builtin_skeleton(
    synthetic_store: Path, tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """Generated = the independent FK's joint positions of the ground truth: FID_k and FID_g
    are 0, so evaluate's ground truth is that skeleton's FK. Every positions metric and the
    record name the skeleton; a model file, when given, replaces it (sha256 recorded)."""
    import hashlib
    import json

    import pyarrow.parquet as pq

    import dancedata
    from tests.featurize.test_motion_families import write_npz_model

    monkeypatch.delenv("DANCEDATA_SMPL_MODEL", raising=False)
    store = dancedata.open_store(synthetic_store)
    gen = tmp_path / "gen"
    gen.mkdir()
    for seq in store.seq_ids(split="train"):
        aa = store.motion(seq, "axis_angle").astype(np.float64)
        trans = store.motion(seq, "trans").astype(np.float64)
        np.save(gen / f"{seq}.npy", brute_force_positions(aa, trans))
    out = tmp_path / "res"
    run_cli("evaluate", str(synthetic_store), "--generated", str(gen), "--split", "train",
            "--out", str(out), "-q")  # fmt: skip
    record = json.loads((out / "results.json").read_text())
    assert record["config"]["skeleton"]["skeleton"] == "edge_smpl_offsets"
    assert record["config"]["smpl_model"] is None
    by_metric = {r["metric"]: r for r in record["results"]}
    # 0 within the accuracy of sqrtm on a singular few-unit covariance (as test_evaluate's own
    # ground truth against itself)
    assert abs(by_metric["fid_k"]["value"]) < 1e-4 and abs(by_metric["fid_g"]["value"]) < 1e-4
    assert by_metric["div_k"]["value"] == pytest.approx(by_metric["div_k_gt"]["value"], rel=1e-9)
    variants = {
        row["metric"]: json.loads(row["variant"])
        for row in pq.read_table(out / "results.parquet").to_pylist()
    }
    for metric in ("fid_k", "fid_g", "div_k", "div_g"):
        assert variants[metric]["skeleton"] == "edge_smpl_offsets", metric
    assert "skeleton" not in variants.get("fpd", {})  # rotations only: no skeleton involved

    model = write_npz_model(tmp_path / "smpl.npz")
    run_cli("evaluate", str(synthetic_store), "--generated", str(synthetic_store), "--split",
            "train", "--smpl-model", str(model), "--out", str(tmp_path / "m"), "-q")  # fmt: skip
    record = json.loads((tmp_path / "m" / "results.json").read_text())
    sha = hashlib.sha256(model.read_bytes()).hexdigest()
    assert record["config"]["skeleton"]["skeleton"] == f"sha256:{sha}"
    assert record["config"]["smpl_model"] == {"file": "smpl.npz", "sha256": sha}
    fid_k = next(r for r in record["results"] if r["metric"] == "fid_k")
    assert fid_k["convention"]["skeleton"] == f"sha256:{sha}"
