"""``dancedata ingest video`` with the pose files and no video (issue 14, item 5): the real
OpenPose folders of the raga examples without their videos, ``--fps`` required, frames
numbered from the JSON file names, sequences found in the pose folder."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from dancedata.ingest.video import ingest_video
from dancedata.store.reader import _VersionReader
from tests.helpers import run_cli
from tests.ingest.test_ingest_video import RAGA, one_line_error, options, write_openpose


def ingest_json(*args: str) -> dict:
    proc = run_cli("ingest", "video", *args, "--json", "-q")
    return json.loads(proc.stdout[proc.stdout.index("{") :])


@pytest.mark.slow
@pytest.mark.real_data
def test_raga_1person_without_its_video_equals_the_ingest_with_it(
    real_data: Path, tmp_path: Path
) -> None:
    folder = real_data / RAGA / "raga_example_1person"
    alone, paired = tmp_path / "alone", tmp_path / "paired"
    summary = ingest_json(
        "--poses", str(folder / "output_json"), "--fps", "25", "--store", str(alone)
    )
    assert summary["version"] == "v1"
    ingest_json(
        str(folder / "short_video.mp4"),
        "--poses",
        str(folder / "output_json"),
        "--store",
        str(paired),
        "--no-music",
    )
    a, b = _VersionReader(alone), _VersionReader(paired)
    (row,) = a.table("sequences").to_pylist()
    assert row["seq_id"] == "video"  # the OpenPose file prefix (video_000000000000_keypoints...)
    assert row["n_frames"] == 125 and row["fps"] == 25.0 and row["video_frames"] == 125
    assert row["width"] is None and row["height"] is None  # no image, no size
    assert row["path"] == str(folder / "output_json") and len(row["sha256"]) == 64
    assert row["music_missing"] and not a.has_table("music")
    clock = summary["counts"]["videos"]["video"]["video"]
    assert clock["fps_source"] == "--fps (no video)"
    assert clock["frame_count_source"] == "OpenPose file numbers" and clock["duration_s"] == 5.0
    # same poses, same tracking, same gap filling as with the video (its clock is 25 fps too)
    for name in ("pose2d", "pose2d_mask"):
        np.testing.assert_array_equal(a.array(f"motion/{name}")[:], b.array(f"motion/{name}")[:])
    assert run_cli("validate", str(alone), check=False).returncode == 0


@pytest.mark.slow
@pytest.mark.real_data
def test_raga_3people_without_its_video_keeps_the_json_frames(
    real_data: Path, tmp_path: Path
) -> None:
    """With its video, this folder is refused (125 JSON frames, 250 video frames) unless
    --allow-drift; alone, the 125 JSON frames are the sequence, at --fps."""
    folder = real_data / RAGA / "raga_example_3people" / "output_json"
    store = tmp_path / "store"
    ingest_json("--poses", str(folder), "--fps", "12.5", "--store", str(store))
    (row,) = _VersionReader(store).table("sequences").to_pylist()
    assert row["n_frames"] == 125 and row["fps"] == 12.5 and row["drift_frames"] == 0
    assert row["tracked_person"] is not None and row["identity_switches"] is not None


@pytest.mark.real_data
def test_without_video_fps_is_required_and_nothing_is_written(
    real_data: Path, tmp_path: Path
) -> None:
    folder = real_data / RAGA / "raga_example_1person" / "output_json"
    store = tmp_path / "store"
    proc = run_cli("ingest", "video", "--poses", str(folder), "--store", str(store), check=False)
    line = one_line_error(proc)
    assert "--fps" in line and str(folder) in line
    assert not store.exists()


@pytest.mark.slow
@pytest.mark.real_data
def test_a_folder_of_pose_folders_gives_one_sequence_each(real_data: Path, tmp_path: Path) -> None:
    root = tmp_path / "poses"
    root.mkdir()
    for name in ("raga_example_1person", "raga_example_3people"):  # links, not copies
        (root / name).symlink_to(real_data / RAGA / name / "output_json")
    store = tmp_path / "store"
    summary = ingest_json("--poses", str(root), "--fps", "25", "--store", str(store))
    rows = _VersionReader(store).table("sequences").to_pylist()
    assert [r["seq_id"] for r in rows] == ["raga_example_1person", "raga_example_3people"]
    assert [r["n_frames"] for r in rows] == [125, 125]
    assert summary["counts"]["sequences"] == 2


def test_frames_numbered_from_file_names_with_gaps(tmp_path: Path) -> None:
    """Files 0, 1, 2, 6 at 10 fps: 7 frames (0.7 s); 3-5 missing (max_gap 0), frame 6 at 0.6 s.
    Two prefixes in one folder: two sequences named after them."""
    poses = tmp_path / "poses"
    write_openpose(poses, 10.0, [0, 1, 2, 6], stem="take1")
    write_openpose(poses, 10.0, range(4), stem="take2")
    store = tmp_path / "store"
    result = ingest_video(store, [], options(poses=poses, fps=10.0, max_gap=0))
    reader = _VersionReader(store)
    rows = {r["seq_id"]: r for r in reader.table("sequences").to_pylist()}
    assert rows["take1"]["n_frames"] == 7 and rows["take2"]["n_frames"] == 4
    pose2d = reader.array("motion/pose2d")[:]
    mask = reader.array("motion/pose2d_mask")[:]
    take1 = slice(rows["take1"]["frame_start"], rows["take1"]["frame_stop"])
    assert (mask[take1][:, 0] == [1, 1, 1, 0, 0, 0, 1]).all()
    # tests.ingest.test_ingest_video.time_pose: joint 0 at x = 100 + 200 t pixels
    np.testing.assert_allclose(pose2d[take1][[0, 2, 6], 0, 0], [100.0, 140.0, 220.0], atol=1e-3)
    assert result.counts["videos"]["take1"]["video"]["duration_s"] == pytest.approx(0.7)


def test_joints_csv_alone_with_fps(tmp_path: Path) -> None:
    csv = tmp_path / "lifter.csv"
    csv.write_text("frame,Nose_x,Nose_y,Nose_z\n0,0,1,2\n1,0.5,1,2\n2,1,1,2\n")
    store = tmp_path / "store"
    ingest_video(store, [], options(joints_csv=csv, fps=2.0))
    reader = _VersionReader(store)
    (row,) = reader.table("sequences").to_pylist()
    assert row["seq_id"] == "lifter" and row["n_frames"] == 3 and row["fps"] == 2.0
    np.testing.assert_allclose(reader.array("motion/positions")[:, 0, 0], [0.0, 0.5, 1.0])
