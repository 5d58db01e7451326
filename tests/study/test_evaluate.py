"""``dancedata evaluate`` end to end on a real (synthetic-content) store, and the generated-motion
readers. The store is built by the CLI (synth → ingest → featurize → segment); generated motion
is the ground truth plus noise, written in the FACT, SMPL-pickle and joint-position layouts; the
record's numbers are checked against direct calls of the metric functions."""

from __future__ import annotations

import json
import pickle
from pathlib import Path

import numpy as np
import pyarrow.parquet as pq
import pytest

import dancedata
from dancedata.compute.rotations import axis_angle_to_rotmat, quat_to_axis_angle
from dancedata.compute.smpl_joints import smpl_joint_positions
from dancedata.errors import InputError
from dancedata.io.generated_motion import read_generated_motion
from dancedata.io.smpl_model import load_smpl_model
from dancedata.metrics import bas_bailando, bas_mint, beat_frames, fid, mse
from tests.featurize.test_motion_families import write_npz_model
from tests.helpers import run_cli

SPLIT = ("--split", "train")  # the 4-sequence synthetic store has crossmodal train only


@pytest.fixture(scope="module")
def store(tmp_path_factory: pytest.TempPathFactory) -> Path:
    root = tmp_path_factory.mktemp("evaluate")
    raw, st = root / "raw", root / "st"
    run_cli("synth", "aist", str(raw), "--sequences", "4", "--seed", "0", "-q")
    run_cli("ingest", "aist", str(raw), "--store", str(st), "-q")
    run_cli("featurize", str(st), "-q")
    run_cli("segment", str(st), "-q")
    return st


@pytest.fixture(scope="module")
def model_path(tmp_path_factory: pytest.TempPathFactory) -> Path:
    return write_npz_model(tmp_path_factory.mktemp("smpl") / "smpl.npz")


def fact_rows(aa: np.ndarray, trans: np.ndarray) -> np.ndarray:
    rot = axis_angle_to_rotmat(aa).reshape(len(aa), -1)
    return np.concatenate([np.zeros((len(aa), 6)), trans, rot], axis=1)


def noisy_motion(store: Path, seed: int = 0) -> dict[str, tuple[np.ndarray, np.ndarray]]:
    """Per train sequence: ground-truth axis-angle + a constant per-joint offset, translation."""
    s = dancedata.open_store(store)
    rng = np.random.default_rng(seed)
    out = {}
    for seq in s.seq_ids(split="train"):
        aa = s.motion(seq, "axis_angle").astype(np.float64)
        out[seq] = (aa + rng.normal(scale=0.05, size=(1, 24, 3)), s.motion(seq, "trans") * 1.0)
    return out


def write_three_layouts(folder: Path, motion: dict, model_path: Path) -> dict[str, str]:
    """One sequence per layout: FACT rows (.npy, batch of 1), SMPL pickle (with scaling),
    joint positions (.npy)."""
    folder.mkdir(parents=True, exist_ok=True)
    model = load_smpl_model(model_path)
    layouts = {}
    for k, (seq, (aa, trans)) in enumerate(sorted(motion.items())):
        if k == 0:
            np.save(folder / f"{seq}.npy", fact_rows(aa, trans)[None])
            layouts[seq] = "fact225"
        elif k == 1:
            data = {
                "smpl_poses": aa.reshape(len(aa), 72),
                "smpl_trans": trans * 95.0,
                "smpl_scaling": np.array([95.0]),
            }
            (folder / f"{seq}.pkl").write_bytes(pickle.dumps(data, protocol=4))
            layouts[seq] = "smpl"
        else:
            np.save(folder / f"{seq}.npy", smpl_joint_positions(model, aa, trans))
            layouts[seq] = "positions"
    return layouts


# ------------------------------------------------------------------------------ readers


def test_reader_recognises_each_layout(tmp_path: Path) -> None:
    rng = np.random.default_rng(0)
    aa = rng.normal(scale=0.3, size=(10, 24, 3))
    trans = rng.normal(size=(10, 3))
    np.save(tmp_path / "a.npy", fact_rows(aa, trans))
    fact = read_generated_motion(tmp_path / "a.npy")
    assert fact.layout == "fact225" and fact.fact_rows.shape == (10, 225)
    (tmp_path / "b.pkl").write_bytes(
        pickle.dumps(
            {
                "smpl_poses": aa.reshape(10, 72),
                "smpl_trans": trans * 2,
                "smpl_scaling": np.array([2.0]),
                "full_pose": rng.normal(size=(10, 24, 3)),
            }
        )
    )
    smpl = read_generated_motion(tmp_path / "b.pkl")
    assert smpl.layout == "smpl" and smpl.positions.shape == (10, 24, 3)
    np.testing.assert_allclose(smpl.trans, trans)
    np.testing.assert_array_equal(smpl.axis_angle, aa)
    np.savez(tmp_path / "c.npz", positions=rng.normal(size=(10, 72)))
    assert read_generated_motion(tmp_path / "c.npz").positions.shape == (10, 24, 3)
    legacy = {
        "pred_motion": axis_angle_to_rotmat(aa).reshape(1, 10, 216),
        "pred_trans": trans[None],
    }
    (tmp_path / "d.pkl").write_bytes(pickle.dumps(legacy))
    np.testing.assert_allclose(
        read_generated_motion(tmp_path / "d.pkl").fact_rows, fact_rows(aa, trans)
    )


@pytest.mark.parametrize(
    ("name", "content", "message"),
    [
        ("bad.npy", lambda p: np.save(p, np.zeros((10, 7))), "unknown generated-motion layout"),
        ("nan.npy", lambda p: np.save(p, np.full((5, 24, 3), np.nan)), "NaN or Inf"),
        ("junk.pkl", lambda p: p.write_bytes(b"\x80\x04not a pickle"), "pickle"),
        ("code.pkl", lambda p: p.write_bytes(pickle.dumps(print)), "unsafe pickle"),
        ("list.pkl", lambda p: p.write_bytes(pickle.dumps([1, 2])), "dict of arrays"),
        ("short.npy", lambda p: np.save(p, np.zeros((1, 225))), "frames"),
        ("text.npy", lambda p: p.write_text("hello"), "cannot read as a numpy file"),
    ],
)
def test_reader_refuses_malformed_files_naming_them(
    tmp_path: Path, name: str, content, message: str
) -> None:
    path = tmp_path / name
    content(path)
    with pytest.raises(InputError, match=message) as info:
        read_generated_motion(path)
    assert name in str(info.value)


# ----------------------------------------------------------------------------- end to end


@pytest.mark.slow
def test_evaluate_cli_matches_direct_metric_calls(
    store: Path, model_path: Path, tmp_path: Path
) -> None:
    motion = noisy_motion(store)
    layouts = write_three_layouts(tmp_path / "gen", motion, model_path)
    out = tmp_path / "res"
    proc = run_cli(
        "evaluate",
        str(store),
        "--generated",
        str(tmp_path / "gen"),
        *SPLIT,
        "--smpl-model",
        str(model_path),
        "--out",
        str(out),
    )
    assert "fid_k" in proc.stdout and "bas_mint" in proc.stdout
    record = json.loads((out / "results.json").read_text())
    table = pq.read_table(out / "results.parquet")
    assert record["store_version"] == dancedata.open_store(store).version
    assert record["split"] == "crossmodal:train" and record["dancedata_version"]
    assert record["generated"]["layouts"] == sorted(set(layouts.values()))
    assert record["n_scored"] == record["n_sequences"] == 3
    by_metric = {r["metric"]: r for r in record["results"]}
    assert set(table.column("metric").to_pylist()) == set(by_metric)
    for row in table.to_pylist():
        assert row["value"] == pytest.approx(by_metric[row["metric"]]["value"], nan_ok=True)
        assert json.loads(row["variant"]) == by_metric[row["metric"]]["convention"]
        assert row["store_version"] == record["store_version"] and row["run_id"]

    # direct calls on the same inputs
    s = dancedata.open_store(store)
    model = load_smpl_model(model_path)
    seqs = sorted(motion)
    gt_pos = [
        smpl_joint_positions(model, s.motion(q, "axis_angle"), s.motion(q, "trans")) for q in seqs
    ]
    gen_pos = [smpl_joint_positions(model, *motion[q]) for q in seqs]
    for kind, name in (("kinetic", "fid_k"), ("geometric", "fid_g")):
        direct = fid(gen_pos, gt_pos, kind).value
        assert by_metric[name]["value"] == pytest.approx(direct, rel=1e-6, abs=1e-6)
    beats = [beat_frames(s.audio(q, "beats")) for q in seqs]
    mint = np.mean([bas_mint(p, b) for p, b in zip(gen_pos, beats, strict=True)])
    bail = np.mean([bas_bailando(p, b) for p, b in zip(gen_pos, beats, strict=True)])
    assert by_metric["bas_mint"]["value"] == pytest.approx(mint, abs=1e-9)
    assert by_metric["bas_bailando"]["value"] == pytest.approx(bail, abs=1e-9)
    # MSE: only the two sequences with rotations; the positions-only one is listed, with why
    rot_seqs = [q for q in seqs if layouts[q] != "positions"]
    from dancedata.compute.rotations import axis_angle_to_euler

    truth = [s.view(q, "thesis_euler_75") for q in rot_seqs]
    recon = [
        np.concatenate(
            [motion[q][1], axis_angle_to_euler(motion[q][0], "XYZ").reshape(len(motion[q][0]), -1)],
            1,
        )
        for q in rot_seqs
    ]
    direct_mse = mse(truth, recon).value
    assert by_metric["mse"]["value"] == pytest.approx(direct_mse, rel=1e-5)
    assert by_metric["mse"]["n_units"] == 2
    positions_only = [q for q in seqs if layouts[q] == "positions"][0]
    assert by_metric["mse"]["unscored"] == [
        {
            "seq_id": positions_only,
            "reason": "generated motion holds joint positions only (no rotations)",
        }
    ]
    assert "not scored " + positions_only in proc.stderr


@pytest.mark.slow
def test_malformed_and_missing_files_are_reported_not_dropped(
    store: Path, model_path: Path, tmp_path: Path
) -> None:
    motion = noisy_motion(store, seed=1)
    gen = tmp_path / "gen"
    write_three_layouts(gen, motion, model_path)
    seqs = sorted(motion)
    # one file malformed (wrong width), one missing
    for suffix in (".npy", ".pkl"):
        (gen / f"{seqs[0]}{suffix}").unlink(missing_ok=True)
        (gen / f"{seqs[1]}{suffix}").unlink(missing_ok=True)
    np.save(gen / f"{seqs[0]}.npy", np.zeros((100, 7)))
    out = tmp_path / "res"
    args = (
        "evaluate",
        str(store),
        "--generated",
        str(gen),
        *SPLIT,
        "--smpl-model",
        str(model_path),
        "--out",
        str(out),
    )
    proc = run_cli(*args)  # exit 0: the record is written, the unscored are listed
    record = json.loads((out / "results.json").read_text())
    assert record["n_scored"] == 1 and record["n_sequences"] == 3
    unscored = {u["seq_id"]: u for u in record["unscored_sequences"]}
    bad_reason = next(iter(unscored[seqs[0]]["reasons"]))
    assert "unknown generated-motion layout" in bad_reason and f"{seqs[0]}.npy" in bad_reason
    assert "no generated file" in next(iter(unscored[seqs[1]]["reasons"]))
    assert f"not scored {seqs[0]}" in proc.stderr and f"not scored {seqs[1]}" in proc.stderr
    # FID needs 2 sequences: skipped with its reason, never a number from one
    assert "fid_k" in record["skipped_metrics"]
    assert all(r["metric"] != "fid_k" for r in record["results"])
    rows = pq.read_table(out / "results.parquet").to_pylist()
    assert rows and all(r["n_unscored"] >= 2 for r in rows)
    assert all(seqs[0] in r["unscored"] for r in rows)
    # --strict: the same record, exit 1
    strict = run_cli(*args, "--strict", check=False)
    assert strict.returncode == 1


@pytest.mark.slow
def test_nothing_scorable_is_one_error_line(store: Path, tmp_path: Path) -> None:
    (tmp_path / "empty").mkdir()
    proc = run_cli(
        "evaluate",
        str(store),
        "--generated",
        str(tmp_path / "empty"),
        *SPLIT,
        "--out",
        str(tmp_path / "res"),
        check=False,
    )
    assert proc.returncode == 1
    assert proc.stderr.startswith("error: ") and "no sequence of the split" in proc.stderr
    assert not (tmp_path / "res").exists()
    bad_split = run_cli(
        "evaluate",
        str(store),
        "--generated",
        str(tmp_path / "empty"),
        "--split",
        "test",
        check=False,
    )
    assert bad_split.returncode == 1 and "has no sequences" in bad_split.stderr


@pytest.mark.slow
def test_ground_truth_against_itself_scores_zero(
    store: Path, model_path: Path, tmp_path: Path
) -> None:
    """The store as its own generated motion: MSE, FID_k, FID_g, FPD, FMD all 0 (FID within
    the accuracy of sqrtm on a singular 3-sample covariance)."""
    out = tmp_path / "res"
    run_cli(
        "evaluate",
        str(store),
        "--generated",
        str(store),
        *SPLIT,
        "--smpl-model",
        str(model_path),
        "--out",
        str(out),
    )
    record = json.loads((out / "results.json").read_text())
    by_metric = {r["metric"]: r["value"] for r in record["results"]}
    assert abs(by_metric["mse"]) < 1e-12  # generated Euler angles recomputed from axis-angle
    assert abs(by_metric["fid_k"]) < 1e-4 and abs(by_metric["fid_g"]) < 1e-4
    assert abs(by_metric["fpd"]) < 1e-4 and abs(by_metric["fmd"]) < 1e-4
    assert by_metric["div_k"] == pytest.approx(by_metric["div_k_gt"])


@pytest.mark.slow
def test_fid_decreases_with_more_keyframes(store: Path, model_path: Path) -> None:
    """The thesis's metric verification (000 §4.1): FID(GT, even + linear SLERP) falls from
    N = 3 to N = 9 (unit: measure, so there are more units than with sequences)."""
    from dancedata.methods.inbetween import linear_slerp, segment_map
    from dancedata.methods.keyframes import even_indices

    s = dancedata.open_store(store)
    model = load_smpl_model(model_path)
    measures = s.measures.to_pylist()
    values = {}
    for n in (3, 5, 9):
        gt_units, rec_units = [], []
        for seq in s.seq_ids():
            rows = [m for m in measures if m["seq_id"] == seq]
            quat, trans = s.motion(seq, "quat"), s.motion(seq, "trans")
            aa = s.motion(seq, "axis_angle")
            starts = np.array([m["frame_start"] for m in rows])
            lengths = np.array([m["frame_stop"] - m["frame_start"] for m in rows])
            kf = np.stack([even_indices(int(length), n) for length in lengths])
            rec = linear_slerp(quat, trans, segment_map(starts, lengths, kf))
            rec_pos = smpl_joint_positions(model, quat_to_axis_angle(rec.quat), rec.trans)
            gt_pos = smpl_joint_positions(model, aa, trans)
            offset = 0
            for start, length in zip(starts, lengths, strict=True):
                rec_units.append(rec_pos[offset : offset + length])
                gt_units.append(gt_pos[start : start + length])
                offset += length
        values[n] = fid(rec_units, gt_units, "kinetic").value
    assert values[3] > values[5] > values[9] > 0, values


# ------------------------------------------------------------------- real AIST++ motions


@pytest.fixture(scope="module")
def real_store(real_data: Path, tmp_path_factory: pytest.TempPathFactory) -> Path:
    """The 4 real AIST++ motions (no music in the real folder), ingested and segmented."""
    store = tmp_path_factory.mktemp("real-evaluate") / "store"
    run_cli(
        "ingest",
        "aist",
        str(real_data / "aist"),
        "--store",
        str(store),
        "--allow-missing-music",
        "-q",
    )
    run_cli("segment", str(store), "-q")
    return store


def _even_slerp(store: dancedata.DanceStore, seq: str, n: int):
    from dancedata.compute.rotations import axis_angle_to_euler, axis_angle_to_quat
    from dancedata.methods.inbetween import linear_slerp, segment_map
    from dancedata.methods.keyframes import even_indices

    rows = [m for m in store.measures.to_pylist() if m["seq_id"] == seq]
    aa, trans = store.motion(seq, "axis_angle"), store.motion(seq, "trans")
    euler = axis_angle_to_euler(aa, "XYZ")
    starts = np.array([m["frame_start"] for m in rows])
    lengths = np.array([m["frame_stop"] - m["frame_start"] for m in rows])
    kf = np.stack([even_indices(int(length), n) for length in lengths])
    segments = segment_map(starts, lengths, kf)
    rec = linear_slerp(axis_angle_to_quat(aa), trans, segments, "XYZ", truth_euler=euler)
    truth = np.concatenate([trans, euler.reshape(len(euler), -1)], axis=1)[segments.frame]
    return rec, truth, starts, lengths, aa, trans


@pytest.mark.slow
@pytest.mark.real_data
def test_real_motions_even_slerp_mse_and_fid_path(real_store: Path, model_path: Path) -> None:
    """docs/EXPERIMENTS.md §7.2 on the real motions: even + linear SLERP, euler75 XYZ pooled MSE
    0.336 / 0.209 / 0.084 for N = 3 / 5 / 9 (within 1e-3), and FID_k(GT, reconstruction)
    falling from N = 3 to 9 (SMPL joints from the synthetic test model: no SMPL ships)."""
    s = dancedata.open_store(real_store)
    model = load_smpl_model(model_path)
    expected = {3: 0.336, 5: 0.209, 9: 0.084}
    fids = {}
    for n in (3, 5, 9):
        truths, recons, gt_units, rec_units = [], [], [], []
        for seq in s.seq_ids():
            rec, truth, starts, lengths, aa, trans = _even_slerp(s, seq, n)
            truths.append(truth)
            recons.append(rec.euler75())
            rec_pos = smpl_joint_positions(model, quat_to_axis_angle(rec.quat), rec.trans)
            gt_pos = smpl_joint_positions(model, aa, trans)
            offset = 0
            for start, length in zip(starts, lengths, strict=True):
                rec_units.append(rec_pos[offset : offset + length])
                gt_units.append(gt_pos[start : start + length])
                offset += length
        result = mse(truths, recons)
        assert result.value == pytest.approx(expected[n], abs=1e-3), (n, result.value)
        assert result.n_frames == sum(len(t) for t in truths)
        fids[n] = fid(rec_units, gt_units, "kinetic").value
    assert fids[3] > fids[5] > fids[9] > 0, fids


@pytest.mark.slow
@pytest.mark.real_data
def test_real_store_against_itself(real_store: Path, model_path: Path, tmp_path: Path) -> None:
    """FID(GT, GT) = 0 on the real motions; without music beats (no music, not featurized)
    every beat metric is skipped and every sequence is listed for it with the reason."""
    out = tmp_path / "res"
    proc = run_cli(
        "evaluate",
        str(real_store),
        "--generated",
        str(real_store),
        *SPLIT,
        "--smpl-model",
        str(model_path),
        "--out",
        str(out),
    )
    record = json.loads((out / "results.json").read_text())
    by_metric = {r["metric"]: r for r in record["results"]}
    assert abs(by_metric["fid_k"]["value"]) < 1e-4 and abs(by_metric["fid_g"]["value"]) < 1e-4
    assert by_metric["fid_k"]["n_units"] == 4
    assert abs(by_metric["mse"]["value"]) < 1e-12
    assert "bas_mint" in record["skipped_metrics"] and "bas_mint" not in by_metric
    assert len(record["unscored_sequences"]) == 4
    for item in record["unscored_sequences"]:
        assert item["reasons"] == {
            "the store has no audio/beats (run featurize with the fact family)": [
                "bas_mint",
                "bas_bailando",
                "bas_msd_motion2music",
                "bas_msd_music2motion",
                "beat_coverage",
                "beat_hit_rate",
                "beat_accuracy",
            ]
        }
    assert proc.stderr.count("the store has no audio/beats") == 4


@pytest.mark.slow
def test_edge_layout_z_up_30_fps_prefixed_names(
    store: Path, model_path: Path, tmp_path: Path
) -> None:
    """EDGE writes ``<epoch>_<name>.pkl`` with smpl_poses / smpl_trans at 30 fps in a z-up
    world (AIST++ rotated +90° about x). Undoing that recovers the ground truth: with
    --generated-fps 30 --generated-up-axis z the MSE is only the 30→60 fps SLERP error, far
    below the same files read as y-up."""
    from dancedata.compute.rotations import rotmat_to_axis_angle

    s = dancedata.open_store(store)
    to_z = np.array([[1.0, 0.0, 0.0], [0.0, 0.0, -1.0], [0.0, 1.0, 0.0]])  # +90° about x
    gen = tmp_path / "edge"
    gen.mkdir()
    for seq in s.seq_ids(split="train"):
        aa = s.motion(seq, "axis_angle").astype(np.float64)[::2]
        trans = s.motion(seq, "trans").astype(np.float64)[::2]
        aa[:, 0] = rotmat_to_axis_angle(to_z @ axis_angle_to_rotmat(aa[:, 0]))
        data = {
            "smpl_poses": aa.reshape(len(aa), 72),
            "smpl_trans": trans @ to_z.T,
            "full_pose": np.zeros((len(aa), 24, 3)),
        }
        (gen / f"0_{seq}.pkl").write_bytes(pickle.dumps(data))
    values = {}
    for axis in ("z", "y"):
        out = tmp_path / f"res-{axis}"
        run_cli(
            "evaluate",
            str(store),
            "--generated",
            str(gen),
            *SPLIT,
            "--smpl-model",
            str(model_path),
            "--generated-fps",
            "30",
            "--generated-up-axis",
            axis,
            "--out",
            str(out),
        )
        record = json.loads((out / "results.json").read_text())
        assert record["n_scored"] == 3 and record["config"]["assumptions"]["generated_fps"] == 30
        values[axis] = {r["metric"]: r["value"] for r in record["results"]}
    assert values["z"]["mse"] < 0.01 * values["y"]["mse"], (values["z"]["mse"], values["y"]["mse"])
    assert values["z"]["fpd"] < 0.01 * values["y"]["fpd"]


@pytest.mark.slow
def test_measure_units_for_fid_and_mse(store: Path, model_path: Path, tmp_path: Path) -> None:
    """--fid-unit measure / --mse-reduce measure_mean: one unit per complete measure of the
    measures table, numbers equal to direct calls on those units."""
    motion = noisy_motion(store, seed=2)
    gen = tmp_path / "gen"
    gen.mkdir()
    for seq, (aa, trans) in motion.items():
        (gen / f"{seq}.pkl").write_bytes(
            pickle.dumps({"smpl_poses": aa.reshape(len(aa), 72), "smpl_trans": trans})
        )
    out = tmp_path / "res"
    run_cli(
        "evaluate",
        str(store),
        "--generated",
        str(gen),
        *SPLIT,
        "--smpl-model",
        str(model_path),
        "--fid-unit",
        "measure",
        "--mse-reduce",
        "measure_mean",
        "--out",
        str(out),
    )
    by_metric = {r["metric"]: r for r in json.loads((out / "results.json").read_text())["results"]}
    s = dancedata.open_store(store)
    model = load_smpl_model(model_path)
    from dancedata.compute.rotations import axis_angle_to_euler

    gt_units, gen_units, truth, recon = [], [], [], []
    for seq in sorted(motion, key=s.seq_ids().index):
        gt_pos = smpl_joint_positions(model, s.motion(seq, "axis_angle"), s.motion(seq, "trans"))
        gen_pos = smpl_joint_positions(model, *motion[seq])
        rows_gen = np.concatenate(
            [motion[seq][1], axis_angle_to_euler(motion[seq][0], "XYZ").reshape(-1, 72)], 1
        )
        rows_gt = s.view(seq, "thesis_euler_75")
        for m in s.measures.to_pylist():
            if m["seq_id"] == seq:
                a, b = m["frame_start"], m["frame_stop"]
                gt_units.append(gt_pos[a:b])
                gen_units.append(gen_pos[a:b])
                truth.append(rows_gt[a:b])
                recon.append(rows_gen[a:b])
    assert by_metric["fid_k"]["n_units"] == len(gt_units) > 3
    assert by_metric["fid_k"]["convention"]["unit"] == "measure"
    assert by_metric["fid_k"]["value"] == pytest.approx(
        fid(gen_units, gt_units, "kinetic").value, rel=1e-6
    )
    direct = mse(truth, recon, reduce="measure_mean")
    assert by_metric["mse"]["value"] == pytest.approx(direct.value, rel=1e-5)
    assert by_metric["mse"]["n_units"] == len(truth)


def test_reader_refuses_oversized_claims_and_survives_corruption(tmp_path: Path) -> None:
    """Never trust a file: headers claiming more than the file holds are refused before
    anything is allocated, and byte-corrupted files raise InputError and nothing else."""
    import io
    import zipfile

    header = io.BytesIO()
    np.lib.format.write_array_header_1_0(
        header, {"descr": "<f8", "fortran_order": False, "shape": (10**6, 10**6)}
    )
    claim = header.getvalue() + b"\0" * 64
    (tmp_path / "huge.npy").write_bytes(claim)
    with pytest.raises(InputError, match="huge.npy"):
        read_generated_motion(tmp_path / "huge.npy")
    with zipfile.ZipFile(tmp_path / "huge.npz", "w") as archive:
        archive.writestr("positions.npy", claim)
    with pytest.raises(InputError, match="claims"):
        read_generated_motion(tmp_path / "huge.npz")

    rng = np.random.default_rng(0)
    aa = rng.normal(size=(6, 24, 3))
    originals = {}
    np.save(tmp_path / "v.npy", fact_rows(aa, rng.normal(size=(6, 3))))
    originals["npy"] = (tmp_path / "v.npy").read_bytes()
    originals["pkl"] = pickle.dumps({"smpl_poses": aa.reshape(6, 72), "smpl_trans": aa[:, 0]})
    np.savez(tmp_path / "v.npz", positions=aa)
    originals["npz"] = (tmp_path / "v.npz").read_bytes()
    outcomes = {"ok": 0, "refused": 0}
    for i in range(300):
        suffix = ("npy", "pkl", "npz")[i % 3]
        data = bytearray(originals[suffix])
        for _ in range(rng.integers(1, 4)):
            data[rng.integers(0, len(data))] = rng.integers(0, 256)
        if i % 7 == 0:
            data = data[: rng.integers(0, len(data))]
        path = tmp_path / f"m{i}.{suffix}"
        path.write_bytes(bytes(data))
        try:
            motion = read_generated_motion(path)
        except InputError as exc:
            assert path.name in str(exc)
            outcomes["refused"] += 1
        else:
            assert motion.n_frames >= 2
            outcomes["ok"] += 1
    assert outcomes["refused"] > 0 and outcomes["ok"] > 0, outcomes


def test_evaluate_sequences_pure_layer_lists_and_guards() -> None:
    """The pure layer: a metric family whose maths fails is skipped with the reason while the
    others are computed; each sequence missing an input is listed under the metrics it misses."""
    from dancedata.study.scoring import EvalSequence, EvaluateParams, evaluate_sequences

    rng = np.random.default_rng(3)
    seqs = []
    for k in range(3):
        pos = np.cumsum(rng.normal(scale=0.01, size=(200, 5, 3)), axis=0)  # 5 joints, not 24
        rows = rng.normal(size=(200, 75))
        seqs.append(
            EvalSequence(
                seq_id=f"s{k}",
                music_id="m0",
                n_frames=200,
                gt_positions=pos,
                gen_positions=pos + 0.001,
                gt_rows=rows,
                gen_rows=rows + 0.1 if k else None,
                music_beats=np.arange(5, 200, 30),
                missing={} if k else {"rotations": "positions only"},
            )
        )
    evaluation = evaluate_sequences(seqs, EvaluateParams(), [{"seq_id": "gone", "reason": "bad"}])
    names = {r.name for r in evaluation.results}
    assert "mse" in names and "bas_mint" in names
    assert "could not be computed" in evaluation.skipped_metrics["fid_g"]
    assert "fid_g" not in names and "fid_k" in names  # kinetic features take any joints
    assert evaluation.unscored["mse"] == [
        {"seq_id": "gone", "reason": "bad"},
        {"seq_id": "s0", "reason": "positions only"},
    ]
    mse_result = next(r for r in evaluation.results if r.name == "mse")
    assert mse_result.n_units == 2 and mse_result.value == pytest.approx(0.01 * 75 / 25)
    with pytest.raises(InputError, match="fid_unit"):
        EvaluateParams(fid_unit="clip")


@pytest.mark.slow
def test_skip_frames_scores_bas_mint_as_mint_does(
    store: Path, model_path: Path, tmp_path: Path
) -> None:
    """--skip-frames 120: mint detects motion beats on the whole generated clip and scores
    frames 120: (calculate_beat_scores.py); the record equals the transcription of mint's code
    (tests/metrics/test_metrics_reference.py) on the same positions and beats."""
    from tests.metrics.test_metrics_reference import (
        ref_mint_alignment_score,
        ref_mint_motion_peak_onehot,
    )

    motion = noisy_motion(store, seed=3)
    gen = tmp_path / "gen"
    gen.mkdir()
    for seq, (aa, trans) in motion.items():
        np.save(gen / f"{seq}.npy", fact_rows(aa, trans))
    out = tmp_path / "res"
    run_cli(
        "evaluate",
        str(store),
        "--generated",
        str(gen),
        *SPLIT,
        "--smpl-model",
        str(model_path),
        "--skip-frames",
        "120",
        "--out",
        str(out),
    )
    record = json.loads((out / "results.json").read_text())
    value = next(r["value"] for r in record["results"] if r["metric"] == "bas_mint")
    s = dancedata.open_store(store)
    model = load_smpl_model(model_path)
    scores = []
    for seq in s.seq_ids(split="train"):
        joints = smpl_joint_positions(model, *motion[seq])
        onehot = np.asarray(s.audio(seq, "beats"))[: len(joints)]
        peaks = ref_mint_motion_peak_onehot(joints)
        scores.append(ref_mint_alignment_score(onehot[120:], peaks[120:]))
    assert value == pytest.approx(float(np.mean(scores)), abs=1e-6)


def test_fid_reference_other_than_paired_ground_truth() -> None:
    """fid_reference train_gt / all_gt: the given reference units normalise and are compared
    with; div_*_gt is the reference's own diversity."""
    from dancedata.metrics import diversity, motion_feature_matrix
    from dancedata.study.scoring import EvalSequence, EvaluateParams, evaluate_sequences

    rng = np.random.default_rng(4)

    def walk(n: int = 150) -> np.ndarray:
        return np.cumsum(rng.normal(scale=0.01, size=(n, 24, 3)), axis=0) + rng.normal(
            size=(1, 24, 3)
        )

    seqs = [
        EvalSequence(
            seq_id=f"s{k}", music_id=None, n_frames=150, gt_positions=walk(), gen_positions=walk()
        )
        for k in range(4)
    ]
    reference = [walk(200) for _ in range(6)]
    params = EvaluateParams(fid_reference="all_gt")
    evaluation = evaluate_sequences(seqs, params, reference_positions=reference)
    by_name = {r.name: r for r in evaluation.results}
    gen = [s.gen_positions for s in seqs]
    assert by_name["fid_k"].value == pytest.approx(fid(gen, reference, "kinetic").value)
    assert by_name["fid_k"].convention["reference"] == "all_gt"
    ref_feats = motion_feature_matrix(reference, "kinetic")
    assert by_name["div_k_gt"].value == pytest.approx(diversity(ref_feats, ref_feats).value)
    assert by_name["div_k_gt"].n_units == 6 and by_name["div_k_gt"].n_frames == 1200
    with pytest.raises(InputError, match="needs"):
        evaluate_sequences(seqs, params)
