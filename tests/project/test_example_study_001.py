"""examples/study_001_genre_lstm.py end to end, run as a user runs it: a store's quaternions and
STFT frames as training windows, a tiny PyTorch LSTM trained for one epoch, its predicted
quaternions (with planted hip flips) ingested back with smoothing and hip repair, exported to
BVH and rendered with the music. On a synthetic AIST++ store, and on the real CMU BVH with the
real Vibe Ace track. Without PyTorch the example says so and exits 1 (checked with torch
hidden); the training tests skip only when torch is absent."""

from __future__ import annotations

import json
import math
import subprocess
import sys
from pathlib import Path

import pytest

from dancedata.io.bvh import read_bvh
from tests.helpers import REPO, importorskip_unless_ci, run_cli

EXAMPLE = REPO / "examples" / "study_001_genre_lstm.py"


def _run(store: Path, out: Path, *args: str) -> dict:
    importorskip_unless_ci("torch")  # skips only without torch, and never under CI=true
    done = subprocess.run(
        [sys.executable, str(EXAMPLE), str(store), str(out), *args],
        capture_output=True,
        text=True,
        timeout=600,
    )
    assert done.returncode == 0, done.stderr
    summary = json.loads((out / "summary.json").read_text())
    assert "trained 1 epoch" in done.stdout and "planted" in done.stdout
    assert "bvh:" in done.stdout
    return summary


def _check(summary: dict, joints: int) -> None:
    training = summary["training"]
    batches = training["batches"]
    assert training["epochs"] == 1 and len(batches) == math.ceil(training["windows"] / 8)
    assert all(math.isfinite(v) for v in batches)
    assert batches[0] == training["first_batch"] and batches[-1] == training["last_batch"]
    # the epoch learnt something: the last batch's loss is below the first batch's, and the
    # loss over all windows after the epoch below the untrained network's
    assert training["last_batch"] < training["first_batch"]
    assert training["all_windows_after"] < training["all_windows_before"]
    assert training["model"]["joints"] == joints
    for seq_id, info in summary["sequences"].items():
        assert info["frames"]["predicted"] == info["frames"]["reference"], seq_id
        assert info["joints"]["predicted"] == info["joints"]["reference"] == joints
        assert info["flips_found"] == info["flips_planted"], seq_id  # every flip, nothing else
        root = info["root_vs_prediction_deg"]
        assert root["ingested"] < root["with_flips"] / 3  # repaired (smoothing moves it a bit)
    assert summary["postprocess"]["smoothing"]["cutoff_hz"] == 6.0
    assert summary["postprocess"]["hip_flips"]["threshold_deg_per_frame"] == 90.0
    clip = read_bvh(Path(summary["bvh"]["path"]))
    assert clip.n_frames == summary["bvh"]["frames"] and summary["bvh"]["joints"] == joints
    av = importorskip_unless_ci("av")
    with av.open(summary["video"]) as container:
        assert {s.type for s in container.streams} == {"video", "audio"}  # with its music


@pytest.mark.slow
def test_on_a_synthetic_aist_store(tmp_path: Path) -> None:
    raw, store = tmp_path / "raw", tmp_path / "ref"
    run_cli("synth", "aist", str(raw), "--sequences", "2", "--seed", "5", "-q")
    run_cli("ingest", "aist", str(raw), "--store", str(store), "-q")
    summary = _run(store, tmp_path / "out", "--render-frames", "30")
    assert len(summary["sequences"]) == 2
    _check(summary, 24)
    # seeded and deterministic: a second run on the featurized store trains the same losses
    again = _run(store, tmp_path / "again", "--sequences", "1", "--render-frames", "10")
    assert again["training"]["batches"] == summary["training"]["batches"]


@pytest.mark.slow
@pytest.mark.real_data
def test_on_the_real_cmu_bvh(real_data: Path, tmp_path: Path) -> None:
    store = tmp_path / "cmu"
    run_cli(
        "ingest", "bvh", str(real_data / "bvh" / "01_01.bvh"), "--store", str(store),
        "--fps", "30", "--units", "0.056444",
        "--music", str(real_data / "audio" / "Kevin_MacLeod_-_Vibe_Ace.hq.ogg"), "--bpm", "120",
        "-q",
    )  # fmt: skip
    summary = _run(store, tmp_path / "out", "--sequences", "1", "--render-frames", "30")
    _check(summary, 31)
    assert summary["training"]["model"]["audio_columns"] == 1025 * 3  # 16 kHz at 30 fps
    text = Path(summary["bvh"]["path"]).read_text()
    assert "CHANNELS 6 Xposition Yposition Zposition Zrotation Yrotation Xrotation" in text


def test_without_torch_it_says_so_and_exits_1(tmp_path: Path) -> None:
    hide_torch = (
        "import runpy, sys; sys.modules['torch'] = None; "
        f"sys.argv = [{str(EXAMPLE)!r}, {str(tmp_path / 'store')!r}, {str(tmp_path / 'out')!r}]; "
        f"runpy.run_path({str(EXAMPLE)!r}, run_name='__main__')"
    )
    done = subprocess.run([sys.executable, "-c", hide_torch], capture_output=True, text=True)
    assert done.returncode == 1
    assert "PyTorch is not installed" in done.stderr and "dancedata[learned]" in done.stderr
    assert not (tmp_path / "out").exists()
