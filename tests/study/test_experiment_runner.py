"""`dancedata experiment run` on a real (synthetic-input) store: configs, runner, records.

The store is built by the real pipeline (synth aist → ingest → featurize → segment) from 6
synthetic sequences; its crossmodal scheme has no test/val sequences, so the runs evaluate the
train split (``--set split.eval=train``). Checks: every shipped config runs and fills every
class D/S cell of its tables; even + linear_slerp MSE equals a direct call of the
in-betweening + MSE functions and a scipy ``Slerp`` loop; without an SMPL model FID cells use
the built-in edge_smpl_offsets skeleton and name it; class M rows fill from --generated
outputs; the record and the run id name everything.
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pyarrow.parquet as pq
import pytest

from dancedata.errors import InputError
from dancedata.study.config import build_config, load_config

# slow: experiment configs run over a featurized 6-sequence store
pytestmark = pytest.mark.slow

REPO = Path(__file__).resolve().parents[2]
CONFIGS = sorted((REPO / "experiments").glob("*.toml"))
EVAL_TRAIN = ["split.eval=train"]


@pytest.fixture(scope="module")
def store(tmp_path_factory) -> Path:
    from dancedata.featurize.featurize import FeaturizeOptions, featurize
    from dancedata.featurize.segment import SegmentOptions, segment
    from dancedata.ingest.aist import AistIngestOptions, ingest_aist
    from dancedata.synth.aist import synth_aist

    root = tmp_path_factory.mktemp("experiment")
    synth_aist(root / "raw", n_sequences=6, seed=0)
    path = root / "store"
    ingest_aist(path, root / "raw", AistIngestOptions())
    featurize(path, FeaturizeOptions())
    segment(path, SegmentOptions())
    return path


@pytest.fixture(scope="module")
def smpl_npz(tmp_path_factory) -> Path:
    """A stand-in SMPL model file in the real .npz layout: 24 'vertices' at the rest joints of
    the toolkit's approximate skeleton, an identity joint regressor (no SMPL model can ship)."""
    from dancedata.compute.smpl import SMPL_PARENTS, SMPL_REST_OFFSETS_M

    rest = np.zeros((24, 3))
    for j, parent in enumerate(SMPL_PARENTS):
        rest[j] = SMPL_REST_OFFSETS_M[j] + (rest[parent] if parent >= 0 else 0.0)
    kintree = np.array([[4294967295, *SMPL_PARENTS[1:]], list(range(24))], dtype=np.int64)
    path = tmp_path_factory.mktemp("smpl") / "stand_in_smpl.npz"
    np.savez(path, J_regressor=np.eye(24), v_template=rest, kintree_table=kintree)
    return path


def run(config_path: Path, store: Path, out: Path, extra: list[str] | None = None, **kw):
    from dancedata.study.runner import run_experiment

    config = load_config(config_path, [*EVAL_TRAIN, *(extra or [])])
    return run_experiment(config, store, out_dir=out, **kw)


def cell_classes(table_id: str) -> dict[str, str]:
    from dancedata.study.tables import seed_tables

    registry = seed_tables()["row_registry"]
    rows = seed_tables()["tables"][table_id]["rows"]
    return {r["label"]: registry[r["row_key"]]["class"] for r in rows}


# ----------------------------------------------------------------------- shipped configs


@pytest.mark.parametrize("config_path", CONFIGS, ids=[p.stem for p in CONFIGS])
def test_every_shipped_config_fills_its_data_and_statistics_cells(
    config_path: Path, store: Path, smpl_npz: Path, tmp_path: Path
) -> None:
    from dancedata.study.tables import build, load_results, render_table

    output = run(config_path, store, tmp_path / "out", smpl_model=smpl_npz)
    rows, skipped = load_results([tmp_path / "out"])
    assert rows and all(np.isfinite(r["value"]) for r in rows)
    config = load_config(config_path)
    assert config.data["tables"], f"{config_path.name} names no table"
    for table_id in config.data["tables"]:
        text = render_table(table_id, rows, skipped)
        if table_id == "demo":
            assert "—" not in text
            continue
        table = build(table_id, rows, skipped)
        classes = cell_classes(table_id)
        for label, line in zip(table.labels, table.cells, strict=True):
            for cell in line:
                if classes[label] == "M":
                    assert cell.value is None and "class M" in (cell.note or ""), (label, cell)
                else:  # D, S and D+audio(+stems+nmfd): a number in every cell, FID included
                    assert cell.value is not None and np.isfinite(cell.value), (table_id, label)
                    assert cell.seed is not None
    assert output.record["split"] == "crossmodal:train"
    if config_path.stem == "thesis-verification":  # the thesis's own check (000 §4.1)
        for metric in ("fid_g", "fid_k"):
            by_n = {r["n_keyframes"]: r["value"] for r in rows
                    if r["row_key"] == "even+linear_slerp" and r["metric"] == metric}  # fmt: skip
            assert by_n[3] > by_n[5] > by_n[9] > 0, (metric, by_n)


def test_without_an_smpl_model_fid_cells_use_the_builtin_skeleton(
    store: Path, smpl_npz: Path, tmp_path: Path, monkeypatch
) -> None:
    """No model file: every FID cell of Tables 4.1 / 4.2 is filled from edge_smpl_offsets
    positions, each FID row and the record name that skeleton; a model file, when given, wins
    (its sha256 in the variant) and changes the run id."""
    import hashlib

    from dancedata.study.tables import build, load_results

    monkeypatch.delenv("DANCEDATA_SMPL_MODEL", raising=False)
    config = REPO / "experiments" / "thesis-verification.toml"
    builtin = run(config, store, tmp_path / "out")
    rows, skipped = load_results([tmp_path / "out"])
    assert {r["metric"] for r in rows} == {"mse", "fid_g", "fid_k"}
    for table_id in ("4.1", "4.2", "4.3"):
        table = build(table_id, rows, skipped)
        assert all(c.value is not None for line in table.cells for c in line), table_id
    fid_rows = [r for r in rows if r["metric"].startswith("fid")]
    assert {json.loads(r["variant"])["skeleton"] for r in fid_rows} == {"edge_smpl_offsets"}
    assert builtin.record["conventions"]["skeleton"]["skeleton"] == "edge_smpl_offsets"
    with_model = run(config, store, tmp_path / "model", smpl_model=smpl_npz)
    sha = hashlib.sha256(smpl_npz.read_bytes()).hexdigest()
    model_rows = [r for r in with_model.rows if r["metric"].startswith("fid")]
    assert {json.loads(r["variant"])["skeleton"] for r in model_rows} == {f"sha256:{sha}"}
    assert with_model.record["run_id"] != builtin.record["run_id"]


# ---------------------------------------------------------------- independent MSE check


def test_even_slerp_mse_equals_direct_calls_and_a_scipy_loop(store: Path, tmp_path: Path) -> None:
    from scipy.spatial.transform import Rotation, Slerp

    import dancedata
    from dancedata.methods.inbetween import linear_slerp, segment_map
    from dancedata.methods.keyframes import even_indices
    from dancedata.metrics.reconstruction_error import mse_euler75

    output = run(REPO / "experiments" / "demo.toml", store, tmp_path / "out")
    got = {r["n_keyframes"]: r["value"] for r in output.rows
           if r["row_key"] == "even+linear_slerp" and r["metric"] == "mse"}  # fmt: skip
    ds = dancedata.open_store(store)
    measures = ds.measure_rows("train")
    seq_ids = list(dict.fromkeys(m["seq_id"] for m in measures))
    assert got and set(got) == {3, 5, 9}
    for n in (3, 5, 9):
        truth, direct, loop = [], [], []
        for seq_id in seq_ids:
            x75 = ds.view(seq_id, "thesis_euler_75").astype(np.float64)
            quat = ds.motion(seq_id, "quat").astype(np.float64)
            trans = ds.motion(seq_id, "trans").astype(np.float64)
            euler = ds.motion(seq_id, "euler").astype(np.float64)
            mine = [m for m in measures if m["seq_id"] == seq_id]
            starts = np.array([m["frame_start"] for m in mine])
            lengths = np.array([m["frame_stop"] - m["frame_start"] for m in mine])
            kf = np.stack([even_indices(int(length), n) for length in lengths])
            seg = segment_map(starts, lengths, kf)
            direct.append(linear_slerp(quat, trans, seg, "XYZ", truth_euler=euler).euler75())
            truth.append(x75[seg.frame])
            for start, length, k in zip(starts, lengths, kf, strict=True):  # scipy, per measure
                frames = np.arange(length)
                q = quat[start : start + length][:, :, [1, 2, 3, 0]]
                angles = np.stack(
                    [Slerp(k, Rotation.from_quat(q[k, j]))(frames).as_euler("XYZ")
                     for j in range(24)], axis=1)  # fmt: skip
                t = np.stack([np.interp(frames, k, trans[start + k, d]) for d in range(3)], 1)
                rows = np.concatenate([t, angles.reshape(length, -1)], axis=1)
                rows[k] = x75[start + k]  # keyframes are the stored rows
                loop.append(rows)
        truth_all = np.concatenate(truth)
        assert got[n] == pytest.approx(mse_euler75(truth_all, np.concatenate(direct)), rel=1e-12)
        assert got[n] == pytest.approx(mse_euler75(truth_all, np.concatenate(loop)), rel=1e-6)
    assert got[3] > got[9] > 0


# ------------------------------------------------------------------- class M: --generated


def test_class_m_rows_fill_from_generated_outputs(store: Path, tmp_path: Path) -> None:
    import dancedata
    from dancedata.study.tables import build, load_results

    config = REPO / "experiments" / "thesis-no-music.toml"
    empty = run(config, store, tmp_path / "none")
    reasons = [s["reason"] for s in empty.record["skipped"]
               if s["row_key"] == "even+transformer_motion"]  # fmt: skip
    assert reasons and all("class M" in r and "--generated" in r for r in reasons)

    ds = dancedata.open_store(store)
    folder = tmp_path / "gen"
    folder.mkdir()
    seq_ids = list(dict.fromkeys(m["seq_id"] for m in ds.measure_rows("train")))
    for seq_id in seq_ids:  # the ground truth itself, as a perfect model would write it
        np.save(folder / f"{seq_id}.npy", ds.view(seq_id, "thesis_euler_75"))
    fact = tmp_path / "fact"  # the layout `dancedata evaluate` reads: FACT (F, 225) rows
    fact.mkdir()
    for seq_id in seq_ids:
        np.save(fact / f"{seq_id}.npy", ds.view(seq_id, "fact_motion_225"))
    generated = {"even+transformer_motion@9": str(folder), "even+transformer_motion@3": str(fact)}
    filled = run(config, store, tmp_path / "gen-out", generated=generated)
    rows, skipped = load_results([tmp_path / "gen-out"])
    table = build("4.4", rows, skipped)
    motion = table.cells[table.labels.index("KF_{even_eulers}/\\hat{D}_{motion}")]
    assert motion[0].value == pytest.approx(0.0, abs=1e-12)  # MSE of the ground truth
    from_fact = build("4.5", rows, skipped).cells[2][0].value
    assert from_fact == pytest.approx(0.0, abs=1e-9)  # rotation matrices → the same Euler rows
    assert filled.record["generated"]["even+transformer_motion@9"]["files"] == len(seq_ids)
    assert filled.record["run_id"] != empty.record["run_id"]  # the outputs' hashes count

    (folder / f"{seq_ids[0]}.npy").unlink()
    partial = run(config, store, tmp_path / "partial",
                  generated={"even+transformer_motion@9": str(folder)})  # fmt: skip
    why = [s["reason"] for s in partial.record["skipped"]
           if s["row_key"] == "even+transformer_motion" and s["n_keyframes"] == 9]  # fmt: skip
    expected = f"miss 1 of {len(seq_ids)} sequences (first: {seq_ids[0]}.npy|.npz|.pkl)"
    assert why and expected in why[0]


# --------------------------------------------------------------- record, run id, config


def test_record_and_parquet_name_every_convention(store: Path, tmp_path: Path) -> None:
    output = run(REPO / "experiments" / "demo.toml", store, tmp_path / "out")
    table = pq.read_table(tmp_path / "out" / "results.parquet")
    assert table.num_rows == 3 * 2 * 3  # strategies × in-betweeners × N, one metric
    types = {f.name: str(f.type) for f in table.schema}
    assert types["n_keyframes"] == "int16" and types["value"] == "double"
    assert types["n_units"] == "int32"
    row = table.to_pylist()[0]
    variant = json.loads(row["variant"])
    assert variant["space"] == "euler75" and variant["wrap"] is False
    assert variant["reduce"] == "pooled" and variant["euler_order"] == "XYZ"
    assert row["split"] == "crossmodal:train" and row["genres_excluded"] == "gJB"
    record = json.loads((tmp_path / "out" / "results.json").read_text())
    assert record["run_id"] == row["run_id"] == output.record["run_id"]
    assert record["store_version"] == row["store_version"] == "v3"
    assert record["conventions"]["keyframes"]["guard"] == 6
    assert record["conventions"]["metrics"]["mse_space"] == "euler75"
    assert record["dancedata_version"]
    again = run(REPO / "experiments" / "demo.toml", store, tmp_path / "again")
    assert again.record["run_id"] == record["run_id"]
    other = run(REPO / "experiments" / "demo.toml", store, tmp_path / "wrap",
                ["metrics.mse_wrap=true"])  # fmt: skip
    assert other.record["run_id"] != record["run_id"]


def test_cli_run_and_table(store: Path, tmp_path: Path) -> None:
    from helpers import run_cli

    out = tmp_path / "cli"
    done = run_cli("experiment", "run", str(REPO / "experiments" / "demo.toml"), "--store",
                   str(store), "--out", str(out), "--set", "split.eval=train")  # fmt: skip
    assert done.returncode == 0, done.stderr
    assert "18 results on crossmodal:train" in done.stdout
    table = run_cli("experiment", "table", "demo", "--results", str(out))
    lines = table.stdout.splitlines()
    assert lines[0].startswith("**Table demo: MSE")
    assert lines[4].startswith("| even+linear_slerp |") and lines[4].count("|") == 5

    bad = run_cli("experiment", "run", str(REPO / "experiments" / "demo.toml"), "--store",
                  str(store), "--out", str(out), check=False)  # fmt: skip
    assert bad.returncode == 1
    last = bad.stderr.strip().splitlines()[-1]
    assert last.startswith("error: split crossmodal:test+val has no sequences")


def test_config_errors_are_one_line(tmp_path: Path) -> None:
    with pytest.raises(InputError, match="unknown key 'metrics.mse_wrapp'"):
        build_config({"rows": ["even+linear_slerp"], "metrics": {"mse_wrapp": True}})
    with pytest.raises(InputError, match="unknown in-betweener 'slerp'"):
        build_config({"rows": ["even+slerp"]})
    with pytest.raises(InputError, match="unknown keyframe strategy"):
        build_config({"rows": ["random+linear_slerp"]})
    with pytest.raises(InputError, match="names no rows"):
        build_config({})
    with pytest.raises(InputError, match="fid_unit"):
        build_config({"rows": ["even+linear_slerp"], "metrics": {"fid_unit": "clip"}})
    bad = tmp_path / "bad.toml"
    bad.write_text("rows = [\n")
    with pytest.raises(InputError, match="not valid TOML") as info:
        load_config(bad)
    assert str(bad) in str(info.value) and "\n" not in str(info.value).strip()
    matrix = build_config({"matrix": {"keyframes": ["even", "dp"], "inbetween": ["linear_slerp"]},
                           "n_keyframes": 5})  # fmt: skip
    assert matrix.data["rows"] == ["even+linear_slerp", "dp+linear_slerp"]
    assert matrix.n_keyframes == [5]
    assert matrix.data["keyframes"]["G"] == 6  # defaults filled, so fingerprinted
