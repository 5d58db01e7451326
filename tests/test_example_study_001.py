"""examples/study_001_genre_lstm.py end to end, run as a user runs it: stand-in network output
(quaternions with jitter and planted hip flips) from a real store, ingested back with smoothing
and hip repair, exported to BVH and rendered. On a synthetic AIST++ store, and on the real CMU
BVH with the real Vibe Ace track."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import pytest

from dancedata.io.bvh import read_bvh
from tests.helpers import REPO, run_cli

EXAMPLE = REPO / "examples" / "study_001_genre_lstm.py"


def _run(store: Path, out: Path, *args: str) -> dict:
    done = subprocess.run(
        [sys.executable, str(EXAMPLE), str(store), str(out), *args],
        capture_output=True,
        text=True,
        timeout=600,
    )
    assert done.returncode == 0, done.stderr
    summary = json.loads((out / "summary.json").read_text())
    assert "planted" in done.stdout and "bvh:" in done.stdout
    return summary


def _check(summary: dict, out: Path, joints: int) -> None:
    for seq_id, info in summary["sequences"].items():
        assert info["flips_found"] == info["flips_planted"], seq_id  # every flip, nothing else
        assert info["root_error_deg"]["ingested"] < info["root_error_deg"]["model_output"] / 3
        assert info["joint_error_deg"]["ingested"] < info["joint_error_deg"]["model_output"]
    assert summary["postprocess"]["smoothing"]["cutoff_hz"] == 6.0
    assert summary["postprocess"]["hip_flips"]["threshold_deg_per_frame"] == 90.0
    clip = read_bvh(Path(summary["bvh"]["path"]))
    assert clip.n_frames == summary["bvh"]["frames"] and summary["bvh"]["joints"] == joints
    assert Path(summary["video"]).stat().st_size > 1000


def test_on_a_synthetic_aist_store(tmp_path: Path) -> None:
    raw, store = tmp_path / "raw", tmp_path / "ref"
    run_cli("synth", "aist", str(raw), "--sequences", "2", "--seed", "5", "-q")
    run_cli("ingest", "aist", str(raw), "--store", str(store), "-q")
    summary = _run(store, tmp_path / "out", "--render-frames", "30")
    assert len(summary["sequences"]) == 2
    _check(summary, tmp_path / "out", 24)


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
    _check(summary, tmp_path / "out", 31)
    text = Path(summary["bvh"]["path"]).read_text()
    assert "CHANNELS 6 Xposition Yposition Zposition Zrotation Yrotation Xrotation" in text
