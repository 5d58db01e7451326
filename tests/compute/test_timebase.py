"""Pose time base: resampling by timestamp, NaN-aware masks, frame-count check, and the
end-to-end alignment error measured on generated videos."""

from __future__ import annotations

from pathlib import Path

import cv2
import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from dancedata.compute.resample import (
    check_frame_count,
    resample_by_time,
    resample_poses,
    target_frame_count,
)
from dancedata.errors import InputError
from dancedata.io.openpose import read_openpose_folder
from dancedata.io.video_clock import read_video_clock

FPS = [24.0, 25.0, 30000 / 1001, 30.0, 50.0, 60.0]


def test_target_frame_count_covers_the_source_span() -> None:
    assert target_frame_count(125, 25, 60) == 300  # 5 s
    assert target_frame_count(125, 25, 20) == 100
    assert target_frame_count(125, 25, 24) == 120
    assert target_frame_count(7, 25, 60) == 17  # 0.28 s → frames at 0 .. 16/60 = 0.267 s
    assert target_frame_count(0, 25, 60) == 0


def test_linear_motion_is_reproduced_and_the_tail_held() -> None:
    n, fps, target = 125, 25.0, 60.0
    t = np.arange(n) / fps
    coords = np.stack([3 * t, -2 * t + 1], axis=-1)[:, None, :]  # (F, 1, 2), pixels
    out = resample_poses(coords, np.ones((n, 1), bool), fps, target)
    tk = np.arange(300) / target
    inside = tk <= t[-1] + 1e-12
    np.testing.assert_allclose(out.coords[inside, 0, 0], 3 * tk[inside], atol=1e-5)
    np.testing.assert_allclose(out.coords[inside, 0, 1], -2 * tk[inside] + 1, atol=1e-5)
    # 4.9667 s and 4.9833 s lie after the last pose frame (4.96 s) but inside its interval.
    assert (~inside).sum() == 2
    np.testing.assert_allclose(out.coords[~inside, 0, 0], 3 * t[-1], atol=1e-5)
    assert out.mask.all()
    np.testing.assert_allclose(out.source_position[inside], tk[inside] * fps, atol=1e-9)
    assert out.source_position[~inside].tolist() == [124.0, 124.0]  # the frame held


def test_downsampling_on_frame_needs_only_that_frame() -> None:
    n = 12
    coords = np.arange(n, dtype=float)[:, None, None].repeat(2, axis=2)
    mask = np.ones((n, 1), bool)
    mask[[1, 4]] = False  # neighbours of frames 0 and 3 (and 6 has both)
    out = resample_poses(coords, mask, 60.0, 20.0)  # every 3rd frame: 0, 3, 6, 9
    assert out.coords.shape == (4, 1, 2)
    assert out.mask[:, 0].tolist() == [True, True, True, True]
    np.testing.assert_array_equal(out.coords[:, 0, 0], [0, 3, 6, 9])


def test_missing_neighbours_make_the_target_missing() -> None:
    n = 10
    coords = np.arange(n, dtype=float)[:, None, None] * np.ones((1, 2, 3))
    mask = np.ones((n, 2), bool)
    mask[5, 0] = False
    out = resample_poses(coords, mask, 10.0, 20.0)  # targets at half frames
    # Joint 0: targets 4.5 and 5.5 (k = 9, 11) and the on-frame 5.0 (k = 10) are missing.
    missing = np.flatnonzero(~out.mask[:, 0])
    assert missing.tolist() == [9, 10, 11]
    assert np.isnan(out.coords[missing, 0]).all() and (out.conf[missing, 0] == 0).all()
    assert out.mask[:, 1].all()
    np.testing.assert_allclose(out.coords[8, 0], 4.0)
    np.testing.assert_allclose(out.coords[12, 0], 6.0)


def test_confidence_is_the_nearest_frame() -> None:
    n = 6
    conf = np.arange(1, n + 1, dtype=float)[:, None] / 10  # frame i has confidence (i+1)/10
    coords = np.zeros((n, 1, 2))
    out = resample_poses(coords, np.ones((n, 1), bool), 10.0, 25.0, conf=conf)
    src = np.arange(out.times.size) * 10.0 / 25.0  # fractional source frame
    nearest = np.where(src - np.floor(src) > 0.5, np.ceil(src), np.floor(src)).astype(int)
    nearest = np.minimum(nearest, n - 1)
    np.testing.assert_allclose(out.conf[:, 0], (nearest + 1) / 10, atol=1e-7)


@settings(max_examples=40, deadline=None)
@given(
    src_fps=st.sampled_from(FPS),
    dst_fps=st.sampled_from(FPS),
    n=st.integers(2, 80),
    seed=st.integers(0, 10_000),
)
def test_fully_known_poses_match_numpy_interp(src_fps, dst_fps, n, seed) -> None:
    values = np.random.default_rng(seed).uniform(-500, 500, (n, 3, 2))
    out = resample_poses(values, np.ones((n, 3), bool), src_fps, dst_fps)
    src_t = np.arange(n) / src_fps
    tk = out.times
    inside = tk <= src_t[-1] + 1e-9
    for j in range(3):
        for d in range(2):
            expected = np.interp(tk[inside], src_t, values[:, j, d])
            np.testing.assert_allclose(out.coords[inside, j, d], expected, atol=1e-3, rtol=1e-6)
    held = out.coords[~inside]
    np.testing.assert_allclose(held, np.broadcast_to(values[-1], held.shape), atol=1e-3)
    assert out.mask.all()


def test_resample_by_time_with_irregular_timestamps() -> None:
    src = np.array([0.0, 0.1, 0.35, 0.4])  # e.g. a lifter CSV's time column
    values = (src * 10)[:, None, None]
    out = resample_by_time(values, np.ones((4, 1), bool), src, np.array([0.05, 0.2, 0.4, 0.5]))
    np.testing.assert_allclose(out.coords[:3, 0, 0], [0.5, 2.0, 4.0], atol=1e-6)
    assert out.mask[:, 0].tolist() == [True, True, True, False]  # no hold by default


# ----------------------------------------------------------------------------- frame-count check


def test_frame_count_check() -> None:
    assert check_frame_count(125, 125, 25.0).frames == 0
    with pytest.raises(
        InputError,
        match=r"120 pose frames \(poses/\) but 125 video frames: "
        r"drift -5 frames \(-0.200 s at 25 fps\)",
    ) as info:
        check_frame_count(120, 125, 25.0, pose_path="poses/", video_path="clip.mp4")
    assert str(info.value).startswith("clip.mp4: ")
    drift = check_frame_count(120, 125, 25.0, allow_drift=True)
    assert (drift.frames, drift.seconds) == (-5, -0.2)
    assert check_frame_count(126, 125, 25.0, tolerance=1).frames == 1


@pytest.mark.real_data
def test_raga_3people_half_the_video_has_poses(real_data: Path) -> None:
    root = real_data / "openpose" / "raga_example_3people"
    poses = read_openpose_folder(root / "output_json")
    clock = read_video_clock(root / "short_video.mp4")
    with pytest.raises(
        InputError,
        match="125 pose frames .* but 250 video frames: drift -125 "
        r"frames \(-5.000 s at 25 fps\)",
    ) as info:
        check_frame_count(
            poses.n_frames,
            clock.n_frames,
            clock.fps,
            pose_path=str(poses.folder),
            video_path=str(clock.path),
        )
    assert str(info.value).startswith(str(clock.path))
    drift = check_frame_count(poses.n_frames, clock.n_frames, clock.fps, allow_drift=True)
    assert drift.to_dict() == {
        "pose_frames": 125,
        "video_frames": 250,
        "fps": 25.0,
        "drift_frames": -125,
        "drift_s": -5.0,
    }


@pytest.mark.real_data
def test_raga_1person_poses_match_the_video(real_data: Path) -> None:
    root = real_data / "openpose" / "raga_example_1person"
    clock = read_video_clock(root / "short_video.mp4")
    drift = check_frame_count(
        read_openpose_folder(root / "output_json").n_frames, clock.n_frames, clock.fps
    )
    assert drift.frames == 0 and drift.seconds == 0.0


# ----------------------------------------------------------------------------- alignment error

X0, SPEED, WIDTH, HEIGHT, SIGMA = 40.0, 180.0, 640, 48, 3.0  # pixels, pixels/second


def _blob_video(path: Path, fps: float, seconds: float, codec: str) -> int:
    """A Gaussian blob whose x encodes the frame's time: x = X0 + SPEED · i / fps pixels."""
    n = int(round(seconds * fps))
    xs, ys = np.meshgrid(np.arange(WIDTH), np.arange(HEIGHT))
    writer = cv2.VideoWriter(str(path), cv2.VideoWriter_fourcc(*codec), fps, (WIDTH, HEIGHT))
    assert writer.isOpened()
    for i in range(n):
        cx = X0 + SPEED * i / fps
        blob = 255 * np.exp(-((xs - cx) ** 2 + (ys - HEIGHT / 2) ** 2) / (2 * SIGMA**2))
        writer.write(cv2.cvtColor(blob.round().astype(np.uint8), cv2.COLOR_GRAY2BGR))
    writer.release()
    return n


def _detect_blobs(path: Path) -> np.ndarray:
    """A stand-in pose estimator: (F, 1, 2) intensity-weighted blob centre of every frame."""
    cap = cv2.VideoCapture(str(path))
    xs = np.arange(WIDTH)
    out = []
    while True:
        ok, frame = cap.read()
        if not ok:
            break
        weight = np.clip(cv2.cvtColor(frame, cv2.COLOR_BGR2GRAY).astype(float) - 20, 0, None)
        total = weight.sum()
        out.append(
            [(weight.sum(0) * xs).sum() / total, (weight.sum(1) * np.arange(HEIGHT)).sum() / total]
        )
    cap.release()
    return np.array(out)[:, None, :]


@pytest.mark.parametrize(
    "fps, codec, suffix, target",
    [
        (25.0, "mp4v", ".mp4", 60.0),
        (30000 / 1001, "MJPG", ".avi", 60.0),
        (30.0, "mp4v", ".mp4", 20.0),
        (25.0, "MJPG", ".avi", 24.0),
    ],
)
def test_alignment_error_on_generated_video(tmp_path, fps, codec, suffix, target) -> None:
    path = tmp_path / f"blob{suffix}"
    n = _blob_video(path, fps, 3.0, codec)
    clock = read_video_clock(path)
    poses = _detect_blobs(path)
    check_frame_count(len(poses), clock.n_frames, clock.fps)  # no drift
    assert clock.n_frames == n

    detector_ms = ((poses[:, 0, 0] - X0) / SPEED - np.arange(n) / fps) * 1000
    out = resample_poses(poses, np.ones((n, 1), bool), clock.fps, target)
    truth = out.times
    inside = truth <= (n - 1) / clock.fps + 1e-9  # held tail excluded: its time is by design
    error_ms = ((out.coords[inside, 0, 0] - X0) / SPEED - truth[inside]) * 1000
    print(
        f"\nalignment {fps:.3f} fps {codec} -> {target:g} fps: fps read {clock.fps!r}, "
        f"{inside.sum()} target frames, time error mean {np.abs(error_ms).mean():.3f} ms, "
        f"max {np.abs(error_ms).max():.3f} ms (detector alone max {np.abs(detector_ms).max():.3f}"
        " ms)"
    )
    assert np.abs(error_ms).max() < 2.0  # a whole frame is 33-42 ms

    # The measurement catches an off-by-one: poses shifted one frame late are 1/fps out.
    shifted = resample_poses(np.roll(poses, 1, axis=0), np.ones((n, 1), bool), clock.fps, target)
    late_ms = ((shifted.coords[inside, 0, 0] - X0) / SPEED - truth[inside]) * 1000
    assert np.median(late_ms) == pytest.approx(-1000 / fps, abs=2.0)
