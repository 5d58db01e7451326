"""examples/study_004_choreograph.py runs end to end (demo store; real AIST++ marked real_data)
and its outputs hold what it says: the segments table, a re-tempoed segment whose length and
factor follow from the spans, the motion at 20 fps, the rendered video, the 60 Hz mel."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import numpy as np
import pyarrow.parquet as pq
import pytest

from dancedata.store.reader import _VersionReader

REPO = Path(__file__).resolve().parents[2]
SCRIPT = REPO / "examples" / "study_004_choreograph.py"


def _run(*args: str) -> str:
    proc = subprocess.run(
        [sys.executable, str(SCRIPT), *args], capture_output=True, text=True, timeout=600
    )
    assert proc.returncode == 0, proc.stdout + proc.stderr
    return proc.stdout


def _check(out: Path, printed: str, music: bool) -> dict:
    summary = json.loads((out / "summary.json").read_text())
    assert "$ dancedata ingest aist" in printed and "re-tempo:" in printed
    assert summary["fps"] == 20.0
    store = Path(summary["store"])
    v20 = _VersionReader(store, summary["versions"]["20fps"])
    v60 = _VersionReader(store, summary["versions"]["60fps"])
    assert v20.group_attrs("motion")["fps"] == 20.0 and v60.group_attrs("motion")["fps"] == 60.0
    for a, b in zip(
        v60.table("sequences").to_pylist(), v20.table("sequences").to_pylist(), strict=True
    ):
        assert b["n_frames"] == (a["n_frames"] - 1) // 3 + 1
    segments = pq.read_table(out / "segments.parquet").to_pylist()
    assert len(segments) == summary["segments"] > 0
    for s in segments:
        assert s["music_stop"] > s["music_start"]
        # about 4 s of music, from beat to beat (tempo grid at 20 fps)
        assert 2.0 <= (s["music_stop"] - s["music_start"]) / 20.0 <= 6.0
    seg = np.load(out / "retimed_segment.npz")
    (s0, s1), (d0, d1) = seg["source_span"], seg["target_span"]
    assert float(seg["factor"]) == pytest.approx((s1 - s0) / (d1 - d0))
    assert summary["factor"] == pytest.approx(float(seg["factor"]))
    assert seg["positions"].shape == (d1 - d0 + 1, 24, 3)
    positions = np.asarray(
        _VersionReader(store, summary["versions"]["study"]).array("motion/positions")[:]
    )
    seq = next(
        s
        for s in _VersionReader(store, summary["versions"]["study"]).table("sequences").to_pylist()
        if s["seq_id"] == summary["picked"]["seq_id"]
    )
    own = positions[seq["frame_start"] : seq["frame_stop"]]
    # the re-tempoed segment starts on the first motion beat's pose and ends on the last's
    np.testing.assert_allclose(seg["positions"][0], own[s0], atol=1e-6)
    np.testing.assert_allclose(seg["positions"][-1], own[s1], atol=1e-6)
    video = Path(summary["video"])
    assert video.is_file() and video.stat().st_size > 1000
    if music:
        assert summary["mel96_shape"] == [3 * (d1 - d0), 96]
        assert np.load(out / "segment_mel96.npy").shape == (3 * (d1 - d0), 96)
    return summary


@pytest.mark.slow
def test_example_on_the_demo_store(tmp_path) -> None:
    printed = _run("--demo", "--out", str(tmp_path / "demo"))
    _check(tmp_path / "demo", printed, music=True)


@pytest.mark.slow
@pytest.mark.real_data
def test_example_on_real_aist(real_data, tmp_path) -> None:
    printed = _run("--raw", str(real_data / "aist"), "--out", str(tmp_path / "real"))
    summary = _check(tmp_path / "real", printed, music=False)
    assert summary["sequences"] == 4
