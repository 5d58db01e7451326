"""``dancedata ingest video``: real OpenPose folders with their videos, generated videos with
generated OpenPose JSON (known clock, time-encoding poses), malformed input via the CLI, and the
chain ingest video → featurize → segment → validate → loader."""

from __future__ import annotations

import json
import math
import re
from pathlib import Path

import cv2
import numpy as np
import pytest
import soundfile as sf

import dancedata
from dancedata.errors import InputError, StoreError
from dancedata.ingest.video import VideoIngestOptions, ingest_video
from dancedata.ingest.video.poses import PoseSettings
from dancedata.io.openpose import BODY_25, COCO_18
from dancedata.store.layout import StoreLayout
from tests.helpers import importorskip_unless_ci, run_cli

RAGA = Path("openpose")
X0, SPEED = 100.0, 200.0  # generated poses: joint x = X0 + SPEED · t + 3 j pixels, t in seconds


# ----------------------------------------------------------------------------- generators


def write_video(path: Path, fps: float, n_frames: int, size=(96, 64)) -> Path:
    """An mp4v video of ``n_frames`` frames at ``fps`` (no audio track)."""
    writer = cv2.VideoWriter(str(path), cv2.VideoWriter_fourcc(*"mp4v"), fps, size)
    assert writer.isOpened()
    for i in range(n_frames):
        image = np.full((size[1], size[0], 3), i % 256, np.uint8)
        writer.write(image)
    writer.release()
    return path


def time_pose(t: float, n_joints: int = 25) -> list[float]:
    """One person whose joints encode the time ``t``: x = X0 + SPEED t + 3 j, y = 40 + 2 j."""
    flat: list[float] = []
    for j in range(n_joints):
        flat += [X0 + SPEED * t + 3 * j, 40.0 + 2 * j, 0.9]
    return flat


def write_openpose(
    folder: Path, fps: float, frames, stem: str = "video", n_joints: int = 25
) -> Path:
    """OpenPose JSON for the given frame numbers, one time-encoding person each."""
    folder.mkdir(parents=True, exist_ok=True)
    for i in frames:
        doc = {
            "version": 1.3,
            "people": [{"person_id": [-1], "pose_keypoints_2d": time_pose(i / fps, n_joints)}],
        }
        (folder / f"{stem}_{i:012d}_keypoints.json").write_text(json.dumps(doc))
    return folder


def write_clicks(path: Path, bpm: float, seconds: float, sr: int = 22050) -> Path:
    """A click track: a short 1 kHz decaying burst on every beat from t = 0."""
    y = np.zeros(int(sr * seconds), np.float32)
    burst = np.sin(2 * np.pi * 1000 * np.arange(400) / sr) * np.exp(-np.arange(400) / 80)
    for t in np.arange(0.0, seconds, 60.0 / bpm):
        i = int(round(t * sr))
        n = min(400, y.size - i)
        y[i : i + n] += burst[:n].astype(np.float32)
    sf.write(path, y, sr)
    return path


def options(**kw) -> VideoIngestOptions:
    settings = {k: kw.pop(k) for k in list(kw) if k in PoseSettings.__dataclass_fields__}
    return VideoIngestOptions(settings=PoseSettings(**settings), **kw)


def generated(tmp_path: Path, fps: float, n_frames: int, name: str = "clip") -> tuple[Path, Path]:
    """A video and its OpenPose folder (one file per video frame)."""
    video = write_video(tmp_path / f"{name}.mp4", fps, n_frames)
    poses = write_openpose(tmp_path / f"{name}_json", fps, range(n_frames))
    return video, poses


def one_line_error(proc) -> str:
    assert proc.returncode == 1, proc.stdout + proc.stderr
    lines = [line for line in proc.stderr.splitlines() if line.strip()]
    assert len(lines) == 1, proc.stderr
    assert "Traceback" not in proc.stderr
    return lines[0]


def snapshot(store: Path) -> dict[str, bytes]:
    """Every file of a store with its bytes (to show a failed command changed nothing)."""
    if not store.exists():
        return {}
    return {str(p.relative_to(store)): p.read_bytes() for p in store.rglob("*") if p.is_file()}


# ----------------------------------------------------------------------------- real data


@pytest.mark.slow
@pytest.mark.real_data
def test_raga_1person_with_music_and_bpm(real_data: Path, tmp_path: Path) -> None:
    folder = real_data / RAGA / "raga_example_1person"
    wav = write_clicks(tmp_path / "click.wav", 120.0, 6.0)
    store = tmp_path / "store"
    proc = run_cli(
        "ingest",
        "video",
        str(folder / "short_video.mp4"),
        "--poses",
        str(folder / "output_json"),
        "--store",
        str(store),
        "--music",
        str(wav),
        "--bpm",
        "120",
        "--genre",
        "raga",
        "--json",
        "-q",
    )
    summary = json.loads(proc.stdout)
    assert summary["version"] == "v1" and summary["created"]
    report = summary["counts"]["videos"]["short_video"]
    assert report["video"]["n_frames"] == 125 and report["video"]["fps"] == 25.0
    assert report["drift"]["poses"]["drift_frames"] == 0
    assert report["tracking"]["identity_switches"] == 0 and report["tracking"]["n_labels"] == 1
    inputs = {
        Path(i["path"]).name: i
        for i in json.loads((store / "versions" / "v1" / "manifest.json").read_text())["inputs"]
    }
    assert inputs["output_json"]["files"] == 125 and inputs["output_json"]["bytes"] == 189_088
    assert set(inputs) == {"short_video.mp4", "output_json", "click.wav"}

    ds = dancedata.open_store(store)
    seq = ds.sequence("short_video")
    assert (seq["source"], seq["genre"], seq["fps"], seq["n_frames"]) == ("video", "raga", 25, 125)
    assert (seq["bpm"], seq["bpm_estimated"], seq["audio_offset"]) == (120.0, False, 0)
    assert (seq["video_frames"], seq["drift_frames"], seq["music_id"]) == (125, 0, "click")
    assert seq["audio_frames"] == 125  # 6 s of music cover the 5 s of poses
    music = ds.music.to_pylist()[0]
    assert (music["sr"], music["n_samples"], music["bpm"]) == (22050, 6 * 22050, 120.0)

    attrs = ds.group_attrs("motion")
    assert attrs["fps"] == 25.0 and attrs["skeleton"]["name"] == "openpose_body25"
    assert attrs["skeleton"]["joints"] == list(BODY_25.joints)
    kp = ds.motion("short_video", "pose2d")
    mask = ds.motion("short_video", "pose2d_mask")
    assert kp.shape == (125, 25, 3) and kp.dtype == np.float32 and mask.dtype == np.uint8
    # Stored values are the raw JSON where detected; NaN with confidence 0 where missing.
    raw = json.loads((folder / "output_json" / "video_000000000007_keypoints.json").read_text())
    flat = np.asarray(raw["people"][0]["pose_keypoints_2d"], np.float32).reshape(25, 3)
    seen = flat[:, 2] > 0
    np.testing.assert_array_equal(kp[7][seen], flat[seen])
    assert (mask[7][seen] == 1).all() and (mask[7][~seen] != 1).all()
    assert np.isnan(kp[mask == 0][:, :2]).all() and (kp[mask == 0][:, 2] == 0).all()
    filled = mask == 2
    assert filled.sum() == report["tracking"]["joints_filled"] > 0
    assert np.isfinite(kp[filled][:, :2]).all() and (kp[filled][:, 2] == 0).all()


@pytest.mark.slow
@pytest.mark.real_data
def test_raga_1person_estimates_bpm_when_not_given(real_data: Path, tmp_path: Path) -> None:
    folder = real_data / RAGA / "raga_example_1person"
    wav = write_clicks(tmp_path / "click.wav", 120.0, 6.0)
    store = tmp_path / "store"
    result = ingest_video(
        store, [folder / "short_video.mp4"], options(poses=folder / "output_json", music=wav)
    )
    ds = dancedata.open_store(store)
    seq = ds.sequence("short_video")
    # beat_track's tempo grid at 22050 Hz / hop 512 puts 120 BPM between 117.5 and 123.0.
    assert seq["bpm"] == pytest.approx(120.0, rel=0.03) and seq["bpm_estimated"] is True
    assert ds.music.to_pylist()[0]["bpm_estimated"] is True
    assert ds.manifest["config"]["bpm_estimate"]["method"] == "librosa.beat.beat_track"
    assert result.counts["bpm_estimated"] == 1


@pytest.mark.slow
@pytest.mark.real_data
def test_raga_3people_drift_refused_then_recorded(real_data: Path, tmp_path: Path) -> None:
    folder = real_data / RAGA / "raga_example_3people"
    wav = write_clicks(tmp_path / "click.wav", 100.0, 11.0)
    store = tmp_path / "store"
    args = [
        "ingest",
        "video",
        str(folder / "short_video.mp4"),
        "--poses",
        str(folder / "output_json"),
        "--store",
        str(store),
        "--music",
        str(wav),
        "--bpm",
        "100",
        "-q",
    ]
    line = one_line_error(run_cli(*args, check=False))
    assert "125 pose frames" in line and "250 video frames" in line
    assert "--allow-drift" in line and "short_video.mp4" in line
    assert not store.exists()

    run_cli(*args, "--allow-drift")
    ds = dancedata.open_store(store)
    seq = ds.sequence("short_video")
    assert (seq["n_frames"], seq["video_frames"], seq["video_frames_used"]) == (125, 250, 125)
    assert seq["drift_frames"] == -125
    report = ds.manifest["counts"]["videos"]["short_video"]
    assert report["drift"]["poses"]["drift_s"] == -5.0
    assert report["tracking"]["n_labels"] == 3 and report["tracking"]["identity_switches"] == 0
    assert ds.manifest["config"]["allow_drift"] is True
    assert ds.manifest["counts"]["drifted_sequences"] == 1
    assert ds.motion("short_video", "pose2d").shape == (125, 25, 3)


@pytest.mark.slow
@pytest.mark.real_data
def test_audio_track_without_pyav_asks_for_the_extra(real_data: Path, tmp_path: Path) -> None:
    folder = real_data / RAGA / "raga_example_3people"  # this clip has an audio track
    hidden = tmp_path / "no_av"  # a package named av that fails to import: PyAV "not installed"
    (hidden / "av").mkdir(parents=True)
    (hidden / "av" / "__init__.py").write_text("raise ImportError('PyAV hidden by the test')\n")
    store = tmp_path / "store"
    proc = run_cli(
        "ingest",
        "video",
        str(folder / "short_video.mp4"),
        "--poses",
        str(folder / "output_json"),
        "--store",
        str(store),
        "--allow-drift",
        "-q",
        check=False,
        env={"PYTHONPATH": str(hidden), "PATH": str(tmp_path)},  # no PyAV, no ffmpeg
    )
    line = one_line_error(proc)
    assert "short_video.mp4" in line and "dancedata[viz]" in line and "--music FILE" in line
    assert not store.exists()


@pytest.mark.slow
def test_video_audio_track_read_with_pyav(tmp_path: Path) -> None:
    """A video whose own audio track (written with PyAV, lossless PCM in MOV) is the music, on a
    PATH without ffmpeg: ingest describes the very samples written (rate, length, channels) and
    estimates from them the tempo librosa finds on the original samples; featurize computes the
    same features from it as from the same samples in a WAV file."""
    import librosa

    from tests.av_media import write_video_with_audio

    importorskip_unless_ci("av")

    sr, seconds, fps = 22050, 6.0, 30.0
    clicks, _ = sf.read(write_clicks(tmp_path / "song.wav", 120.0, seconds, sr), dtype="float32")
    stereo = np.stack([clicks, 0.5 * clicks])
    stereo = (np.clip(np.round(stereo * 32768.0), -32768, 32767) / 32768.0).astype(np.float32)
    video = write_video_with_audio(tmp_path / "clip.mov", fps, 180, stereo, sr, "pcm_s16le")
    poses = write_openpose(tmp_path / "clip_json", fps, range(180))
    store = tmp_path / "store"
    args = ["ingest", "video", str(video), "--poses", str(poses), "--store", str(store), "-q"]
    run_cli(*args, env={"PATH": str(tmp_path)})  # no ffmpeg program on PATH
    ds = dancedata.open_store(store)
    row = ds.music.to_pylist()[0]
    assert row["music_source"] == "video_audio" and Path(row["path"]).name == "clip.mov"
    assert (row["sr"], row["n_samples"], row["channels"]) == (sr, stereo.shape[1], 2)
    assert row["duration_s"] == pytest.approx(seconds)
    tempo, _ = librosa.beat.beat_track(y=stereo.mean(axis=0), sr=sr, hop_length=512)
    assert row["bpm_estimated"] and row["bpm"] == pytest.approx(float(np.atleast_1d(tempo)[0]))
    assert row["bpm"] == pytest.approx(120.0, rel=0.05)

    # featurize decodes the track from the video too (PyAV, no ffmpeg): the same features as
    # from the same mono samples in a WAV file given with --music.
    wav = tmp_path / "mixdown.wav"
    sf.write(wav, stereo.mean(axis=0), sr, subtype="FLOAT")
    reference = tmp_path / "reference"
    run_cli(*args[:6], str(reference), "--music", str(wav), "--bpm", str(row["bpm"]), "-q")
    for folder in (store, reference):
        run_cli("featurize", str(folder), "--stems", "none", "-q", env={"PATH": str(tmp_path)})
    track, ref = dancedata.open_store(store), dancedata.open_store(reference)
    for name in ("onset_env", "mfcc", "beats"):
        np.testing.assert_allclose(
            track.audio("clip", name), ref.audio("clip", name), rtol=1e-5, atol=1e-5
        )


# ----------------------------------------------------------------------------- generated videos


@pytest.mark.parametrize(
    "video_fps, n_video, target_fps",
    [(30.0, 47, 25.0), (25.0, 40, 60.0), (29.97, 31, 30.0), (24.0, 29, None)],
)
def test_generated_video_resampled_on_its_clock(
    tmp_path: Path, video_fps: float, n_video: int, target_fps: float | None
) -> None:
    video, poses = generated(tmp_path, video_fps, n_video)
    store = tmp_path / "store"
    ingest_video(store, [video], options(poses=poses, fps=target_fps))
    ds = dancedata.open_store(store)
    fps = target_fps or video_fps
    expected = math.ceil(n_video * fps / video_fps - 1e-9)  # target times inside the video
    seq = ds.sequence("clip")
    assert seq["n_frames"] == expected and seq["fps"] == fps
    assert seq["music_missing"] is True and seq["bpm"] is None  # mp4v clip: no audio track
    kp = ds.motion("clip", "pose2d").astype(np.float64)
    mask = ds.motion("clip", "pose2d_mask")
    assert kp.shape == (expected, 25, 3)

    times = np.arange(expected) / fps
    inside = times <= (n_video - 1) / video_fps + 1e-9  # later target times hold the last pose
    decoded = (kp[:, :, 0] - X0 - 3 * np.arange(25)) / SPEED  # each joint tells the time
    error_ms = np.abs(decoded[inside] - times[inside, None]) * 1000
    assert error_ms.max() < 1e-3, f"alignment error {error_ms.max():.6f} ms"
    np.testing.assert_allclose(decoded[~inside], (n_video - 1) / video_fps, atol=1e-6)
    assert (mask == 1).all() and (kp[..., 2] == np.float32(0.9)).all()


def test_decoded_frame_times_agree_on_a_constant_rate_video(tmp_path: Path) -> None:
    video, poses = generated(tmp_path, 30.0, 37)
    results = {}
    for mode in ("nominal", "decoded"):
        ingest_video(tmp_path / mode, [video], options(poses=poses, fps=25.0, frame_times=mode))
        ds = dancedata.open_store(tmp_path / mode)
        results[mode] = ds.motion("clip", "pose2d")
        assert ds.manifest["config"]["frame_times"] == mode
    np.testing.assert_allclose(results["decoded"], results["nominal"], atol=1e-3)
    report = dancedata.open_store(tmp_path / "decoded").manifest["counts"]["videos"]["clip"]
    assert report["decoded_times_max_deviation_ms"] < 1e-3
    assert report["video"]["frame_count_source"] == "decoded"


def test_gaps_filled_up_to_max_gap_and_masked(tmp_path: Path) -> None:
    fps, n = 25.0, 30
    frames = [i for i in range(n) if i not in (5, 6) and not 12 <= i < 18]
    video = write_video(tmp_path / "clip.mp4", fps, n)
    poses = write_openpose(tmp_path / "json", fps, frames)
    store = tmp_path / "store"
    result = ingest_video(store, [video], options(poses=poses, max_gap=3))
    ds = dancedata.open_store(store)
    kp, mask = ds.motion("clip", "pose2d"), ds.motion("clip", "pose2d_mask")
    assert (mask[[5, 6]] == 2).all() and (mask[12:18] == 0).all()
    assert (mask[frames] == 1).all()
    # Interpolated across the short gap: linear poses come back exactly, confidence 0.
    np.testing.assert_allclose(kp[[5, 6], 0, 0], X0 + SPEED * np.array([5, 6]) / fps, rtol=1e-6)
    assert (kp[[5, 6], :, 2] == 0).all() and np.isnan(kp[12:18, :, :2]).all()
    tracking = result.counts["videos"]["clip"]["tracking"]
    assert tracking["joints_filled"] == 2 * 25 and tracking["frames_with_dancer"] == n - 8
    assert tracking["frames_filled"] == 2 == ds.sequence("clip")["frames_filled"]
    assert result.counts["videos"]["clip"]["pose_files_missing"] == 8


def test_gap_filled_flag_survives_resampling(tmp_path: Path) -> None:
    fps, n = 20.0, 20
    video = write_video(tmp_path / "clip.mp4", fps, n)
    poses = write_openpose(tmp_path / "json", fps, [i for i in range(n) if i != 10])
    ingest_video(tmp_path / "s", [video], options(poses=poses, fps=40.0, max_gap=1))
    mask = dancedata.open_store(tmp_path / "s").motion("clip", "pose2d_mask")[:, 0]
    # Target frames 19, 20, 21 (0.475, 0.5, 0.525 s) touch the filled source frame 10 (0.5 s).
    assert mask[19:22].tolist() == [2, 2, 2] and (np.delete(mask, [19, 20, 21]) == 1).all()


def test_joints_csv_with_and_without_openpose(tmp_path: Path) -> None:
    fps, n = 25.0, 20
    video, poses = generated(tmp_path, fps, n)
    rng = np.random.default_rng(0)
    names = list(BODY_25.joints)
    order = rng.permutation(25)  # the lifter writes its joints in its own order
    metres = rng.normal(size=(n, 25, 3))
    header = ["frame"] + [f"{names[j]}_{a}" for j in order for a in "xyz"]
    lines = [",".join(header)]
    for i in range(n):
        if i == 4:
            continue  # a frame the lifter missed
        cells = [str(i + 1)] + [f"{v:.6f}" for j in order for v in metres[i, j] * 1000.0]
        lines.append(",".join(cells))
    csv = tmp_path / "clip.csv"
    csv.write_text("\n".join(lines) + "\n")

    store = tmp_path / "store"
    result = ingest_video(
        store,
        [video],
        options(poses=poses, joints_csv=csv, units="mm", frame_base=1, max_gap=0),
    )
    ds = dancedata.open_store(store)
    pos, pmask = ds.motion("clip", "positions"), ds.motion("clip", "positions_mask")
    assert pos.shape == (n, 25, 3) and pos.dtype == np.float32
    known = np.ones(n, bool)
    known[4] = False
    np.testing.assert_allclose(pos[known], metres[known], atol=1e-6)
    assert np.isnan(pos[4]).all() and (pmask[4] == 0).all() and (pmask[known] == 1).all()
    attrs = ds.group_attrs("motion")
    assert attrs["skeleton"]["name"] == "openpose_body25"
    assert ds.zarr("motion/positions").attrs["units"] == "m"
    assert ds.motion("clip", "pose2d").shape == (n, 25, 3)
    assert result.counts["videos"]["clip"]["joints_csv"]["units"] == "mm"

    # Headerless, COCO-18 order, no OpenPose at all: positions only.
    plain = tmp_path / "plain.csv"
    coco = rng.normal(size=(n, 18, 3))
    plain.write_text("\n".join(",".join(f"{v:.6f}" for v in row.ravel()) for row in coco))
    store2 = tmp_path / "store2"
    ingest_video(store2, [video], options(joints_csv=plain, skeleton="coco18"))
    ds2 = dancedata.open_store(store2)
    assert ds2.array_names() == ["motion/positions", "motion/positions_mask"]
    assert ds2.group_attrs("motion")["skeleton"]["joints"] == list(COCO_18.joints)
    np.testing.assert_allclose(ds2.motion("clip", "positions"), coco, atol=1e-6)
    with pytest.raises(InputError, match="--skeleton"):
        ingest_video(tmp_path / "store3", [video], options(joints_csv=plain))


@pytest.mark.slow
def test_several_videos_map_to_pose_folders(tmp_path: Path) -> None:
    poses = tmp_path / "poses"
    a = write_video(tmp_path / "a.mp4", 25.0, 10)
    b = write_video(tmp_path / "b.mp4", 25.0, 15)
    write_openpose(poses / "a", 25.0, range(10))  # rule 1: a subfolder per video
    write_openpose(poses, 25.0, range(15), stem="b")  # rule 2: <stem>_<frame>_keypoints.json
    store = tmp_path / "store"
    ingest_video(store, [a, b], options(poses=poses))
    rows = dancedata.open_store(store).sequences.to_pylist()
    assert [(r["seq_id"], r["frame_start"], r["frame_stop"]) for r in rows] == [
        ("a", 0, 10),
        ("b", 10, 25),
    ]
    c = write_video(tmp_path / "c.mp4", 30.0, 12)
    with pytest.raises(InputError, match="no OpenPose output for this video") as info:
        ingest_video(store, [a, c], options(poses=poses))
    assert str(c) in str(info.value)
    write_openpose(poses / "c", 30.0, range(12))
    with pytest.raises(InputError, match="pass --fps"):
        ingest_video(store, [a, c], options(poses=poses))
    result = ingest_video(store, [a, c], options(poses=poses, fps=30.0))
    ds = dancedata.open_store(store, result.version)
    assert [r["n_frames"] for r in ds.sequences.to_pylist()] == [12, 12]  # 10 @25 → 12 @30

    (poses / "c" / "video_000000000003_keypoints.json").write_text('{"version": 1.3}')
    d = write_video(tmp_path / "d.mp4", 30.0, 12)  # no poses at all: the whole video is skipped
    result = ingest_video(store, [a, c, d], options(poses=poses, fps=30.0, on_error="skip"))
    ds = dancedata.open_store(store, result.version)
    skipped = ds.manifest["skipped"]
    assert [Path(s["path"]).name for s in skipped] == ["d.mp4", "video_000000000003_keypoints.json"]
    assert "no OpenPose output" in skipped[0]["error"]
    assert "no 'people' list" in skipped[1]["error"]
    assert ds.seq_ids() == ["a", "c"]
    assert (ds.motion("c", "pose2d_mask")[3] == 2).all()  # the bad file's frame, gap-filled


def test_same_inputs_write_nothing(tmp_path: Path) -> None:
    video, poses = generated(tmp_path, 25.0, 10)
    store = tmp_path / "store"
    first = ingest_video(store, [video], options(poses=poses))
    again = ingest_video(store, [video], options(poses=poses))
    assert first.created and not again.created and again.version == first.version
    changed = ingest_video(store, [video], options(poses=poses, fps=50.0))
    assert changed.created and changed.version == "v2"


MALFORMED = {
    "missing_people": ('{"version": 1.3}', "no 'people' list"),
    "wrong_keypoint_count": (
        json.dumps({"people": [{"pose_keypoints_2d": [1.0] * 72}]}),
        "72 pose values, expected 75",
    ),
    "truncated": (
        json.dumps({"people": [{"pose_keypoints_2d": time_pose(0.0)}]})[:90],
        "not valid JSON \\(file truncated",
    ),
}


@pytest.mark.slow
@pytest.mark.parametrize("case", sorted(MALFORMED))
def test_malformed_json_is_one_clear_error_and_store_untouched(tmp_path: Path, case: str) -> None:
    video, poses = generated(tmp_path, 25.0, 12)
    store = tmp_path / "store"
    ingest_video(store, [video], options(poses=poses))
    before = snapshot(store)
    text, message = MALFORMED[case]
    bad = poses / "video_000000000005_keypoints.json"
    bad.write_text(text)
    proc = run_cli(
        "ingest",
        "video",
        str(video),
        "--poses",
        str(poses),
        "--store",
        str(store),
        "-q",
        check=False,
    )
    line = one_line_error(proc)
    assert line.startswith(f"error: {bad}: ")
    assert re.search(message, line), line
    assert snapshot(store) == before
    assert StoreLayout(store).committed_versions() == ["v1"]


# ----------------------------------------------------------------------------- the full chain


@pytest.mark.slow
def test_chain_ingest_featurize_segment_validate_loader(tmp_path: Path) -> None:
    video, poses = generated(tmp_path, 25.0, 100)  # 4 s of video, stored at 30 fps
    wav = write_clicks(tmp_path / "song.wav", 120.0, 4.0)
    store = tmp_path / "store"
    run_cli(
        "ingest",
        "video",
        str(video),
        "--poses",
        str(poses),
        "--store",
        str(store),
        "--music",
        str(wav),
        "--bpm",
        "120",
        "--fps",
        "30",
        "-q",
    )
    run_cli("featurize", str(store), "-q")
    run_cli("segment", str(store), "-q")
    assert run_cli("validate", str(store)).returncode == 0

    ds = dancedata.open_store(store)
    assert ds.version == "v3"
    featurized = StoreLayout(store).read_manifest("v2")["counts"]
    assert "axis_angle" in featurized["motion_absent"]["rotations"]
    assert not any(n.startswith("motion/rot") for n in ds.array_names())
    kp = ds.motion("clip", "pose2d")
    assert kp.shape == (120, 25, 3)
    assert ds.audio_frames("clip") == 120
    # Audio runs at the motion rate (sr = 30 × 512): clicks every 0.5 s peak every 15 frames.
    assert ds.group_attrs("audio")["sr"] == 15360
    env = ds.audio("clip", "onset_env")
    peaks = [
        k
        for k in range(1, 119)
        if env[k] == env[max(0, k - 3) : k + 4].max() and env[k] > 0.5 * env.max()
    ]
    assert peaks and all(min(abs(p - 15 * round(p / 15)), 99) <= 1 for p in peaks), peaks
    assert ds.view("clip", "fact_audio_35").shape == (120, 35)
    with pytest.raises(StoreError, match="holds no joint rotations .*sources: video"):
        ds.view("clip", "fact_motion_225")
    measures = ds.measures.to_pylist()  # 60 / 120 × 4 × 30 = 60 frames a measure
    assert [(m["frame_start"], m["frame_stop"]) for m in measures] == [(0, 60), (60, 120)]
    windows = list(ds.iter_measures(motion=None))
    assert [w.audio.shape for w in windows] == [(60, 35), (60, 35)]
