"""examples/inbetween_transformer end to end: train a tiny model on a synthetic store, write its
outputs as <seq_id>.npy FACT rows, score them with `dancedata evaluate` (docs/EXPERIMENTS.md §3.3).

The example's scripts run as a user runs them (subprocesses). Skipped without torch (the
optional 'stems' or 'learned' extra); `make test` installs it.
"""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

# slow: trains the example in-betweening transformer (torch)
pytestmark = pytest.mark.slow

pytest.importorskip("torch")

ROOT = Path(__file__).resolve().parents[2]
EXAMPLE = ROOT / "examples" / "inbetween_transformer"
DANCEDATA = Path(sys.executable).with_name("dancedata")
TINY = ["--size", "tiny", "--epochs", "6", "--lr", "3e-3", "--batch-size", "16", "--val-split", ""]


def script(name: str, *args: object, check: bool = True) -> subprocess.CompletedProcess:
    done = subprocess.run(
        [sys.executable, str(EXAMPLE / name), *map(str, args)],
        capture_output=True,
        text=True,
        timeout=300,
    )
    if check:
        assert done.returncode == 0, done.stderr
    return done


@pytest.fixture(scope="module")
def store(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """12 synthetic AIST++ sequences (train 5, val 3, test 3 on the crossmodal split), ingested
    with its motion featurized (rotation matrices; no audio: the motion variant needs none) and
    segmented into measures: a real store."""
    from dancedata.featurize.featurize import FeaturizeOptions, featurize
    from dancedata.featurize.segment import SegmentOptions, segment
    from dancedata.ingest.aist import AistIngestOptions, ingest_aist
    from dancedata.synth.aist import synth_aist

    root = tmp_path_factory.mktemp("transformer")
    synth_aist(root / "raw", n_sequences=12, seed=0)
    path = root / "store"
    ingest_aist(path, root / "raw", AistIngestOptions())
    featurize(path, FeaturizeOptions(audio=False))
    segment(path, SegmentOptions())
    return path


@pytest.fixture(scope="module")
def trained(store: Path, tmp_path_factory: pytest.TempPathFactory) -> Path:
    out = tmp_path_factory.mktemp("run") / "tiny3.pt"
    script("train.py", store, "--keyframes", 3, "--out", out, *TINY)
    return out


def test_training_lowers_the_loss(trained: Path) -> None:
    summary = json.loads(trained.with_suffix(".json").read_text())
    before, after = summary["loss_before"], summary["loss_after"]
    # The output layer starts at zero: before training the model returns X_lin exactly.
    assert 0 < after["train"] < before["train"]
    assert len(summary["history"]) == 6
    assert summary["training"]["padding"] == "zeros + key mask"


def _rotations_ok(rows: np.ndarray) -> None:
    r = rows[:, 9:].reshape(len(rows), 24, 3, 3).astype(np.float64)
    assert np.abs(r @ np.swapaxes(r, -1, -2) - np.eye(3)).max() < 1e-5
    assert np.abs(np.linalg.det(r) - 1).max() < 1e-5


def measure_ends(store: Path, split: str) -> dict[str, int]:
    """seq_id → end frame of its last complete measure."""
    import dancedata

    ends: dict[str, int] = {}
    for r in dancedata.open_store(store).measure_rows(split, "crossmodal"):
        ends[r["seq_id"]] = max(ends.get(r["seq_id"], 0), r["frame_stop"])
    return ends


def evaluate_mse(store: Path, folder: Path, out: Path) -> dict:
    done = subprocess.run(
        [
            str(DANCEDATA),
            "evaluate",
            str(store),
            "--generated",
            str(folder),
            "--split",
            "test",
            "--out",
            str(out),
        ],
        capture_output=True,
        text=True,
        timeout=300,
    )
    assert done.returncode == 0, done.stderr
    results = json.loads((out / "results.json").read_text())
    assert results["n_scored"] == results["n_sequences"] > 0
    return next(r for r in results["results"] if r["metric"] == "mse")


@pytest.fixture(scope="module")
def generated(store: Path, trained: Path, tmp_path_factory: pytest.TempPathFactory) -> dict:
    """The tiny model's and the keyframe baseline's files for the test split, and their MSE
    from `dancedata evaluate`."""
    root = tmp_path_factory.mktemp("generated")
    out = {"model": root / "model", "baseline": root / "baseline"}
    script("generate.py", store, "--checkpoint", trained, "--split", "test", "--out", out["model"])
    script("generate.py", store, "--baseline", "--keyframes", 3, "--split", "test", "--out",
           out["baseline"])  # fmt: skip
    mse = {name: evaluate_mse(store, folder, root / f"eval-{name}") for name, folder in out.items()}
    return {"folders": out, "mse": mse}


def test_generated_files_are_fact_rows_per_test_sequence(store: Path, generated: dict) -> None:
    ends = measure_ends(store, "test")
    out = generated["folders"]["model"]
    assert sorted(p.stem for p in out.glob("*.npy")) == sorted(ends)
    for seq_id, end in ends.items():
        rows = np.load(out / f"{seq_id}.npy")
        assert rows.shape == (end, 225) and rows.dtype == np.float32
        assert not rows[:, :6].any() and np.isfinite(rows).all()
        _rotations_ok(rows)
    manifest = json.loads((out / "generated.json").read_text())
    assert manifest["method"] == "even+transformer_motion" and manifest["n_keyframes"] == 3
    assert manifest["skipped"] == {}
    # The model changed the in-betweens (its output is not X_lin).
    first = sorted(ends)[0]
    base = np.load(generated["folders"]["baseline"] / f"{first}.npy")
    assert np.abs(np.load(out / f"{first}.npy") - base).max() > 1e-4


def test_evaluate_scores_them_and_the_runner_fills_the_class_m_row(
    store: Path, generated: dict, tmp_path: Path
) -> None:
    ends = measure_ends(store, "test")
    for mse in generated["mse"].values():
        assert np.isfinite(mse["value"]) and mse["value"] > 0
        assert mse["n_frames"] == sum(ends.values())
        assert mse["convention"]["space"] == "euler75"
    folders = generated["folders"]
    done = subprocess.run(
        [str(DANCEDATA), "experiment", "run", str(ROOT / "experiments" / "thesis-no-music.toml"),
         "--store", str(store), "--out", str(tmp_path / "exp"), "--set", "split.eval=test",
         "--set", "n_keyframes=[3]", "--set", 'metrics.names=["mse"]',
         "--set", 'rows=["even+linear_slerp", "even+transformer_motion"]',
         "--generated", f"even+transformer_motion@3={folders['model']}"],
        capture_output=True,
        text=True,
        timeout=300,
    )  # fmt: skip
    assert done.returncode == 0, done.stderr
    import pyarrow.parquet as pq

    rows = pq.read_table(tmp_path / "exp" / "results.parquet").to_pylist()
    value = {r["row_key"]: r["value"] for r in rows if r["metric"] == "mse"}
    # The runner scores the measures' frames, which are exactly the files' frames: both paths
    # give the same number, for the model and for the baseline (the runner's own SLERP).
    assert value["even+transformer_motion"] == pytest.approx(generated["mse"]["model"]["value"],
                                                             rel=1e-6)  # fmt: skip
    assert value["even+linear_slerp"] == pytest.approx(generated["mse"]["baseline"]["value"],
                                                       rel=1e-5)  # fmt: skip


def test_baseline_is_even_keyframes_plus_slerp(store: Path, tmp_path: Path) -> None:
    """--baseline rows: ground truth at the even keyframes, scipy's Slerp between them."""
    from scipy.spatial.transform import Rotation, Slerp

    import dancedata

    ds = dancedata.open_store(store)
    script(
        "generate.py", store, "--baseline", "--keyframes", 5, "--split", "val", "--out", tmp_path
    )
    row = ds.measure_rows("val", "crossmodal")[1]
    truth = ds.view(row["seq_id"], "fact_motion_225")[row["frame_start"] : row["frame_stop"]]
    got = np.load(tmp_path / f"{row['seq_id']}.npy")[row["frame_start"] : row["frame_stop"]]
    length = len(truth)
    keys = np.floor(np.arange(5) * (length - 1) / 4 + 0.5).astype(int)
    np.testing.assert_allclose(got[keys], truth[keys], atol=1e-5)
    frames = np.arange(length)
    for joint in (0, 7, 16):
        blocks = truth[:, 9 + 9 * joint : 18 + 9 * joint].reshape(-1, 3, 3)
        expect = Slerp(keys, Rotation.from_matrix(blocks[keys]))(frames).as_matrix()
        np.testing.assert_allclose(
            got[:, 9 + 9 * joint : 18 + 9 * joint].reshape(-1, 3, 3), expect, atol=1e-5
        )
    trans = np.stack([np.interp(frames, keys, truth[keys, 6 + c]) for c in range(3)], axis=1)
    np.testing.assert_allclose(got[:, 6:9], trans, atol=1e-5)


def test_bad_checkpoint_is_one_error_line(store: Path, tmp_path: Path) -> None:
    bogus = tmp_path / "bogus.pt"
    bogus.write_bytes(b"not a checkpoint")
    done = script("generate.py", store, "--checkpoint", bogus, "--out", tmp_path / "o", check=False)
    assert done.returncode == 1
    lines = done.stderr.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("error: ") and "bogus.pt" in lines[0]
    assert not list((tmp_path / "o").glob("*.npy")) if (tmp_path / "o").exists() else True


def _example_model():
    """examples/inbetween_transformer/model.py, imported under a name no test module uses."""
    import importlib.util

    name = "inbetween_example_model"
    if name not in sys.modules:
        spec = importlib.util.spec_from_file_location(name, EXAMPLE / "model.py")
        module = importlib.util.module_from_spec(spec)
        sys.modules[name] = module  # dataclasses look their module up there
        spec.loader.exec_module(module)
    return sys.modules[name]


@pytest.mark.parametrize(
    "variant", ["motion", "genre", "merged_full", "merged_drum", "cross_full", "cross_drum"]
)
def test_every_variant_starts_at_x_lin_and_ignores_padding(variant: str) -> None:
    """Untrained: residual exactly 0 (the output layer starts at zero). With random output
    weights, the real frames' output does not depend on how much padding follows them."""
    import torch

    m = _example_model()
    torch.manual_seed(0)
    cfg = m.ModelConfig(variant=variant, d_model=16, layers=1, heads=2, ffn=32, dropout=0.0,
                        max_len=40, genre_dim=6, audio_dim=22)  # fmt: skip
    model = m.InbetweenTransformer(cfg).eval()
    x = torch.randn(2, 30, 225)
    genre = torch.eye(6)[:2]
    audio = torch.randn(2, 30, 22)
    pad = torch.zeros(2, 30, dtype=torch.bool)
    pad[1, 20:] = True
    with torch.no_grad():
        assert not model(x, pad, genre, audio).any()
        torch.nn.init.normal_(model.output.weight)
        full = model(x, pad, genre, audio)
        short = model(x[1:, :20], pad[1:, :20], genre[1:], audio[1:, :20])
    assert full.shape == (2, 30, 225) and not full[..., :6].any()
    torch.testing.assert_close(full[1, :20], short[0], atol=1e-4, rtol=1e-4)
    with pytest.raises(ValueError, match="max_len"):
        model(torch.zeros(1, 41, 225), torch.zeros(1, 41, dtype=torch.bool), genre[:1],
              torch.zeros(1, 41, 22))  # fmt: skip


def test_frames_before_the_first_measure_hold_the_first_keyframe(
    store: Path, tmp_path: Path
) -> None:
    """With a downbeat phase of 17 frames no measure covers frames 0…16: the file still starts
    at the sequence's frame 0, those frames hold the first keyframe, and the manifest counts
    them."""
    import shutil

    import dancedata
    from dancedata.featurize.segment import SegmentOptions, segment

    copy = tmp_path / "store"
    shutil.copytree(store, copy)
    segment(copy, SegmentOptions(phase_frames=17))
    out = tmp_path / "out"
    script("generate.py", copy, "--baseline", "--keyframes", 3, "--split", "test", "--out", out)
    ds = dancedata.open_store(copy)
    ends = measure_ends(copy, "test")
    manifest = json.loads((out / "generated.json").read_text())
    for seq_id, end in ends.items():
        rows = np.load(out / f"{seq_id}.npy")
        truth = ds.view(seq_id, "fact_motion_225")
        assert rows.shape == (end, 225)
        np.testing.assert_allclose(rows[:17], np.repeat(truth[17:18], 17, axis=0), atol=1e-5)
        np.testing.assert_allclose(rows[17], truth[17], atol=1e-5)
        assert manifest["written"][seq_id]["baseline_frames"] == 17
