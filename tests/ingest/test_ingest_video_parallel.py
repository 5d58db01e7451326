"""``dancedata ingest video`` on the ingest engine: ``--workers 2`` writes the same bytes as one
process, a SIGKILLed run resumes with the videos it finished reading, and a video that
disagrees with the first (frame rate) fails the run even under ``--on-error skip``.

Real processes throughout (the CLI in a subprocess, a real SIGKILL), generated videos and
OpenPose JSON in their real on-disk formats."""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

from dancedata.store.layout import StoreLayout
from dancedata.store.reader import _VersionReader
from dancedata.store.validate import validate_store
from tests.helpers import run_cli
from tests.ingest.test_ingest_video import one_line_error, snapshot, write_openpose, write_video


def videos_with_poses(folder: Path, n_videos: int, n_frames: int, fps: float = 25.0) -> Path:
    """``n_videos`` videos v00.mp4 … with their OpenPose JSON in ``folder/poses/<stem>/``."""
    folder.mkdir(parents=True, exist_ok=True)
    for k in range(n_videos):
        stem = f"v{k:02d}"
        write_video(folder / f"{stem}.mp4", fps, n_frames + k)
        write_openpose(folder / "poses" / stem, fps, range(n_frames + k), stem=stem)
    return folder


def ingest_args(folder: Path, store: Path, *extra: str) -> list[str]:
    videos = sorted(str(p) for p in folder.glob("*.mp4"))
    poses = str(folder / "poses")
    return ["ingest", "video", *videos, "--poses", poses, "--store", str(store), *extra]


def data_checksums(store: Path, version: str = "v1") -> dict[str, str]:
    """checksums.json 'files' entries of a version (path → sha256)."""
    recorded = json.loads((store / "versions" / version / "checksums.json").read_text())
    return {path: entry["sha256"] for path, entry in recorded["files"].items()}


def same_data(a: Path, b: Path) -> bool:
    """Arrays and tables byte for byte (the manifest differs: creation time, counts)."""
    x, y = data_checksums(a), data_checksums(b)
    return x == y and any(p.startswith("data.zarr/motion/pose2d/") for p in x)


@pytest.mark.slow
def test_two_workers_write_the_same_bytes_as_one(tmp_path: Path) -> None:
    folder = videos_with_poses(tmp_path / "in", n_videos=4, n_frames=30)
    serial, parallel = tmp_path / "serial", tmp_path / "parallel"
    run_cli(*ingest_args(folder, serial, "--no-music", "-q"))
    run_cli(*ingest_args(folder, parallel, "--no-music", "--workers", "2", "-q"))
    assert same_data(serial, parallel)
    tables = [p for p in data_checksums(serial) if p.endswith(".parquet")]
    assert len(tables) == 2  # sequences and splits (no music)
    a, b = _VersionReader(serial).manifest, _VersionReader(parallel).manifest
    assert a["counts"] == b["counts"] and a["inputs"] == b["inputs"]
    assert a["counts"]["units"] == 4 and a["counts"]["sequences"] == 4  # one task per video
    rows = _VersionReader(parallel).table("sequences").to_pylist()
    assert [r["frame_start"] for r in rows] == [0, 30, 61, 93]  # 30, 31, 32, 33 frames


@pytest.mark.slow
@pytest.mark.parametrize("workers", ["1", "2"])
def test_a_killed_ingest_resumes_with_the_videos_it_finished(tmp_path: Path, workers: str) -> None:
    """SIGKILL to the whole process group (worker processes too) once a video is finished,
    then the same command again (same --workers)."""
    folder = videos_with_poses(tmp_path / "in", n_videos=6, n_frames=400)
    args = ingest_args(folder, tmp_path / "store", "--no-music", "--workers", workers)
    reference = tmp_path / "reference"
    run_cli(*ingest_args(folder, reference, "--no-music", "-q"))

    store = tmp_path / "store"
    layout = StoreLayout(store)
    proc = subprocess.Popen(
        [sys.executable, "-m", "dancedata.cli", *args, "-q"],
        stdout=subprocess.DEVNULL,
        stderr=subprocess.DEVNULL,
        start_new_session=True,
    )
    deadline = time.monotonic() + 300
    markers: list[Path] = []
    while proc.poll() is None and time.monotonic() < deadline:
        markers = [m for t in layout.temp_dirs() for m in t.glob(".build/*/videos/[!.]*.json")]
        if markers:
            break
        time.sleep(0.005)
    assert proc.poll() is None and markers, "the ingest finished before a video could be seen"
    os.killpg(proc.pid, signal.SIGKILL)
    proc.wait()
    assert layout.temp_dirs(), "the killed run should have left its build behind"
    assert not list((store / "versions").glob("v*"))

    out = run_cli(*args).stdout
    assert "v1" in out
    counts = _VersionReader(store).manifest["counts"]
    assert counts["units"] == 6 and 1 <= counts["resumed_units"] < 6, counts
    assert same_data(store, reference)
    assert validate_store(store) == [] and layout.temp_dirs() == []


def test_a_video_at_another_frame_rate_fails_even_when_skipping(tmp_path: Path) -> None:
    folder = tmp_path / "in"
    folder.mkdir()
    write_video(folder / "a.mp4", 25.0, 10)
    write_openpose(folder / "poses" / "a", 25.0, range(10), stem="a")
    write_video(folder / "b.mp4", 30.0, 12)
    write_openpose(folder / "poses" / "b", 30.0, range(12), stem="b")
    store = tmp_path / "store"
    before = snapshot(store)
    args = ingest_args(folder, store, "--no-music", "--on-error", "skip", "-q")
    line = one_line_error(run_cli(*args, check=False))
    assert "b.mp4" in line and "frame rate 30 differs from 25 of a.mp4" in line, line
    assert snapshot(store) == before
