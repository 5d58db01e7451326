"""``dancedata render``: real stores (synthetic AIST++ through the real pipeline, a real BVH
file, video poses), real MP4 files, decoded again with PyAV.

Checked: frame count and frame rate equal the sequence's; the audio lasts as long as the motion
(within one frame) and is the music from the right time (correlation at zero lag); decoded pixels
show the skeleton where the projection puts its joints and background away from every bone; up
is up for each source; forward kinematics, SMPL joints and generated files give the positions
they should.
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

import dancedata
from dancedata.compute.camera import screen_axes
from dancedata.viz.skeleton_draw import BACKGROUND, MusicTiming, timing_at
from tests.helpers import importorskip_unless_ci, run_cli

av = importorskip_unless_ci("av")

from dancedata.viz.render import (  # noqa: E402
    RenderOptions,
    SkeletonRenderer,
    render_sequence,
    skeleton_frames,
)
from dancedata.viz.skeleton_source import load_skeleton  # noqa: E402

# slow: encodes MP4 video (PyAV) and decodes it again
pytestmark = pytest.mark.slow

BG_RGB = np.array(BACKGROUND[::-1], dtype=np.int32)


# ----------------------------------------------------------------------------- stores


@pytest.fixture(scope="module")
def aist_store(small_featurized_store: Path) -> Path:
    """The session's 2-sequence synthetic AIST++ store (synth seed 0 → ingest → featurize →
    segment; tests/conftest.py). Rendering only reads it: motion, music, measures and beats,
    none of which depend on the stems the shared store was featurized with."""
    return small_featurized_store


@pytest.fixture(scope="module")
def bvh_store(tmp_path_factory, real_data: Path) -> Path:
    store = tmp_path_factory.mktemp("bvh") / "store"
    run_cli(
        "ingest", "bvh", str(real_data / "bvh" / "freya_edit.bvh"), "--store", str(store),
        "--fps", "25", "--music", str(real_data / "audio" / "snare-accelerate.ogg"),
        "--bpm", "120", "-q",
    )  # fmt: skip
    run_cli("featurize", str(store), "--stems", "none", "-q")
    run_cli("segment", str(store), "-q")
    return store


def first_seq(store: Path) -> str:
    return dancedata.open_store(store).seq_ids()[0]


# ----------------------------------------------------------------------------- decoding


def decode(path: Path) -> dict:
    """Every video frame (RGB), the video rate, and the audio samples (mono) with their rate."""
    with av.open(str(path)) as container:
        video = container.streams.video[0]
        rate = video.average_rate
        durations = {s.type: float(s.duration * s.time_base) for s in container.streams}
        frames = [f.to_ndarray(format="rgb24") for f in container.decode(video)]
    audio, sr = None, None
    with av.open(str(path)) as container:
        if container.streams.audio:
            stream = container.streams.audio[0]
            sr = stream.codec_context.sample_rate
            chunks = [f.to_ndarray().mean(axis=0) for f in container.decode(stream)]
            audio = np.concatenate(chunks)
    return {"frames": frames, "rate": rate, "audio": audio, "sr": sr, "durations": durations}


def segment_distance(points: np.ndarray, a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Distance of each of (N, 2) points to the segment a–b."""
    ab = b - a
    t = np.clip(((points - a) @ ab) / max(float(ab @ ab), 1e-12), 0.0, 1.0)
    return np.linalg.norm(points - (a + t[:, None] * ab), axis=1)


def check_pixels(image: np.ndarray, pixels: np.ndarray, parents, area) -> None:
    """Joint centres differ from the background; points far from every bone and joint are
    background (so the skeleton is where the projection says, and nowhere else)."""
    finite = np.isfinite(pixels).all(axis=1)
    assert finite.sum() >= 5
    for x, y in np.rint(pixels[finite]).astype(int):
        colour = image[y, x].astype(np.int32)
        assert np.abs(colour - BG_RGB).max() > 60, (x, y, colour)
    x0, y0, w, h = area
    grid = np.stack(
        np.meshgrid(np.arange(x0 + 8, x0 + w - 8, 7), np.arange(y0 + 8, y0 + h - 8, 7)), -1
    ).reshape(-1, 2)
    near = np.full(len(grid), np.inf)
    for j in np.flatnonzero(finite):
        near = np.minimum(near, np.linalg.norm(grid - pixels[j], axis=1))
    # ``parents`` (J,) or the (B, 2) bones drawn (SkeletonStyle.bones: with the extra bones)
    pairs = parents if isinstance(parents, np.ndarray) else list(enumerate(parents))
    for j, p in pairs:
        if p >= 0 and finite[j] and finite[p]:
            near = np.minimum(near, segment_distance(grid, pixels[j], pixels[p]))
    far = grid[near > 14]
    assert len(far) > 100
    colours = image[far[:, 1], far[:, 0]].astype(np.int32)
    off = np.abs(colours - BG_RGB).max(axis=1)
    # Lossy H.264: background pixels stay within a few levels; floor line aside (1 px grey).
    assert np.mean(off <= 12) > 0.97, np.sort(off)[-20:]


# ----------------------------------------------------------------------------- pure parts


@pytest.mark.parametrize("up", ["y", "z", "x", "-y", "-z"])
@pytest.mark.parametrize("view", ["front", "side", "top"])
def test_screen_axes_are_orthonormal_and_right_handed(up: str, view: str) -> None:
    right, screen_up = screen_axes(up, view)
    sign = -1.0 if up.startswith("-") else 1.0
    up_vec = sign * np.eye(3)["xyz".index(up[-1])]
    assert right @ screen_up == 0 and np.linalg.norm(right) == 1 == np.linalg.norm(screen_up)
    toward_viewer = np.cross(right, screen_up)
    if view == "top":
        np.testing.assert_array_equal(toward_viewer, up_vec)  # looking down from above
    else:
        np.testing.assert_array_equal(screen_up, up_vec)  # up is up
    if up == "y" and view == "front":
        np.testing.assert_array_equal(right, [1, 0, 0])  # x right, camera on +z


def test_measure_and_beat_by_brute_force() -> None:
    starts, stops = np.array([0, 40, 80]), np.array([40, 80, 120])
    beats = np.array([3, 13, 23, 33, 43, 53, 63, 73, 83, 93, 103, 113])
    timing = MusicTiming(starts, stops, beats, 4)
    for frame in range(0, 130):
        m = next((k for k in range(3) if starts[k] <= frame < stops[k]), -1)
        past = beats[beats <= frame]
        since = int(frame - past[-1]) if past.size else None
        beat = int(((beats >= starts[m]) & (beats <= frame)).sum()) if m >= 0 else 0
        assert timing_at(timing, frame) == (m, beat, since), frame


# ----------------------------------------------------------------------------- AIST++ store


def test_aist_render_frames_fps_audio_and_pixels(aist_store: Path, tmp_path: Path) -> None:
    ds = dancedata.open_store(aist_store)
    seq = first_seq(aist_store)
    row = ds.sequence(seq)
    out = tmp_path / "aist.mp4"
    proc = run_cli("render", str(aist_store), seq, str(out), "--json", "-q")
    summary = json.loads(proc.stdout)
    assert summary["panels"][0]["source"] == "keypoints3d" and summary["audio"]
    got = decode(out)
    assert len(got["frames"]) == row["n_frames"] == 640
    assert got["rate"] == 60 and got["frames"][0].shape == (480, 640, 3)
    # Audio lasts as long as the motion, within one frame: decoded samples, and the streams'
    # durations as the container tells a player (AAC priming trimmed by the edit list).
    assert abs(got["audio"].size / got["sr"] - row["n_frames"] / row["fps"]) <= 1 / row["fps"]
    assert got["durations"]["video"] == pytest.approx(row["n_frames"] / row["fps"], abs=1e-3)
    assert got["durations"]["audio"] == pytest.approx(got["durations"]["video"], abs=1e-3)
    # ... and is the music from its start: correlation with the wav at zero lag.
    music = music_at(ds, seq, 0, row["n_frames"], got["sr"])
    n = min(music.size, got["audio"].size)
    assert np.corrcoef(music[2048:n], got["audio"][2048:n])[0, 1] > 0.9

    renderer = SkeletonRenderer(ds, seq, RenderOptions())
    for k in (0, 333, 639):
        pixels = renderer.pixels[0][k]
        if np.isfinite(pixels).all(axis=1).sum() < 5:
            continue
        check_pixels(
            got["frames"][k], pixels, renderer.styles[0].bones, renderer.layout.drawing_area(0)
        )
    # y-up: the nose (joint 0) is drawn above the ankles (15, 16) on every frame it exists.
    kp = ds.motion(seq, "keypoints3d")
    ok = np.isfinite(kp[:, [0, 15, 16], 1]).all(axis=1)
    px = renderer.pixels[0]
    assert (px[ok, 0, 1] < px[ok, 15, 1]).all() and (px[ok, 0, 1] < px[ok, 16, 1]).all()
    # Orthographic front view: pixel offsets are the x/y offsets times one scale, y flipped.
    scale = renderer.panels[0].camera.scale
    k = int(np.flatnonzero(ok)[0])
    np.testing.assert_allclose(
        px[k, 15] - px[k, 0], scale * np.array([1, -1]) * (kp[k, 15, :2] - kp[k, 0, :2]),
        rtol=1e-5, atol=1e-3,
    )  # fmt: skip


def music_at(ds, seq: str, start: int, stop: int, sr: int) -> np.ndarray:
    """The sequence's music for frames [start, stop), read with soundfile and resampled."""
    import librosa
    import soundfile as sf

    row = ds.sequence(seq)
    track = {m["music_id"]: m for m in ds.music.to_pylist()}[row["music_id"]]
    y, native = sf.read(track["path"], dtype="float32", always_2d=True)
    y = librosa.resample(y.mean(axis=1), orig_sr=native, target_sr=sr)
    t0 = (row["audio_offset"] + start) / row["fps"]
    return y[int(round(t0 * sr)) : int(round((t0 + (stop - start) / row["fps"]) * sr))]


def test_frame_range_cuts_video_and_audio(aist_store: Path, tmp_path: Path) -> None:
    ds = dancedata.open_store(aist_store)
    seq = first_seq(aist_store)
    out = tmp_path / "cut.mp4"
    result = render_sequence(ds, seq, out, RenderOptions(start=200, stop=500, view="side"))
    assert (result.frames, result.start, result.stop) == (300, 200, 500)
    got = decode(out)
    assert len(got["frames"]) == 300
    assert abs(got["audio"].size / got["sr"] - 300 / 60) <= 1 / 60
    music = music_at(ds, seq, 200, 500, got["sr"])
    n = min(music.size, got["audio"].size)
    corr = np.corrcoef(music[2048 : n - 2400], got["audio"][2048 : n - 2400])[0, 1]
    assert corr > 0.9, corr
    # In sync to the millisecond: the cross-correlation peaks at lag 0 within ±50 ms.
    lags = np.arange(-2400, 2401, 8)
    score = [music[3000 : n - 3000] @ got["audio"][3000 + lag : n - 3000 + lag] for lag in lags]
    assert abs(int(lags[int(np.argmax(score))])) <= got["sr"] // 1000
    # The first rendered frame is sequence frame 200, drawn with the side camera.
    renderer = SkeletonRenderer(ds, seq, RenderOptions(start=200, stop=500, view="side"))
    check_pixels(
        got["frames"][0],
        renderer.pixels[0][200],
        renderer.styles[0].bones,
        renderer.layout.drawing_area(0),
    )
    # skeleton_frames gives the same images as RGB arrays (before compression).
    first = next(skeleton_frames(ds, seq, RenderOptions(start=200, stop=500, view="side")))
    assert first.shape == (480, 640, 3) and first.dtype == np.uint8
    assert np.abs(first.astype(int) - got["frames"][0].astype(int)).mean() < 4


def test_smpl_joints_with_a_model_file(aist_store: Path, tmp_path: Path) -> None:
    from tests.featurize.test_motion_families import (
        reference_smpl_positions,
        smpl_parts,
        write_npz_model,
    )

    model = write_npz_model(tmp_path / "smpl.npz")
    ds = dancedata.open_store(aist_store)
    seq = first_seq(aist_store)
    track = load_skeleton(ds, seq, smpl_model=model)
    assert track.source == "smpl" and track.positions.shape == (640, 24, 3)
    expected = reference_smpl_positions(
        smpl_parts(), ds.motion(seq, "axis_angle").astype(np.float64), ds.motion(seq, "trans")
    )
    np.testing.assert_allclose(track.positions, expected, atol=1e-5)
    out = tmp_path / "smpl.mp4"
    run_cli("render", str(aist_store), seq, str(out), "--smpl-model", str(model),
            "--start", "0", "--stop", "30", "-q")  # fmt: skip
    assert len(decode(out)["frames"]) == 30
    # Without the model, the SMPL source draws the built-in edge_smpl_offsets skeleton, named
    # in the panel's label (its numbers: tests/ops/test_smpl_skeleton.py).
    from dancedata.ops.smpl_skeletons import smpl_skeleton

    builtin = load_skeleton(ds, seq, source="smpl")
    assert builtin.source == "smpl" and "edge_smpl_offsets" in builtin.label
    want = smpl_skeleton(None).positions(ds.motion(seq, "axis_angle"), ds.motion(seq, "trans"))
    np.testing.assert_allclose(builtin.positions, want, atol=1e-6)
    run_cli("render", str(aist_store), seq, str(out), "--source", "smpl", "--start", "0",
            "--stop", "10", "-q")  # fmt: skip
    assert len(decode(out)["frames"]) == 10


# ----------------------------------------------------------------------------- BVH store


@pytest.mark.real_data
def test_bvh_render_up_axis_fk_and_side_by_side(
    bvh_store: Path, aist_store: Path, tmp_path: Path
) -> None:
    ds = dancedata.open_store(bvh_store)
    seq = first_seq(bvh_store)
    row = ds.sequence(seq)
    # Forward kinematics of the stored rotations reproduces the stored positions.
    fk = load_skeleton(ds, seq, source="fk")
    np.testing.assert_allclose(fk.positions, ds.motion(seq, "positions"), atol=2e-4)
    out = tmp_path / "bvh.mp4"
    aist_seq = first_seq(aist_store)
    run_cli("render", str(bvh_store), seq, str(out), "--compare", f"{aist_store}::{aist_seq}",
            "-q")  # fmt: skip
    got = decode(out)
    assert len(got["frames"]) == row["n_frames"] == 147 and got["rate"] == 25
    assert abs(got["audio"].size / got["sr"] - 147 / 25) <= 1 / 25
    options = RenderOptions(compare=(f"{aist_store}::{aist_seq}",))
    renderer = SkeletonRenderer(ds, seq, options)
    assert len(renderer.panels) == 2
    joints = list(renderer.panels[0].track.joints)
    head, foot = joints.index("Head"), joints.index("LeftFoot")
    for k in (10, 100):
        px = renderer.pixels[0][k]
        assert px[head, 1] < px[foot, 1]  # BVH y-up: head above the feet
        check_pixels(
            got["frames"][k], px, renderer.panels[0].track.parents, renderer.layout.drawing_area(0)
        )
        # Panel 2 shows the AIST++ sequence at the same time (60 fps: frame 2.4 k).
        j = renderer.panel_frame(1, k)
        assert j == int(np.floor(k / 25 * 60 + 1e-6))
        check_pixels(
            got["frames"][k],
            renderer.pixels[1][j],
            renderer.panels[1].track.parents,
            renderer.layout.drawing_area(1),
        )


def test_generated_positions_side_by_side(aist_store: Path, tmp_path: Path) -> None:
    ds = dancedata.open_store(aist_store)
    seq = first_seq(aist_store)
    generated = tmp_path / "generated"
    generated.mkdir()
    kp = ds.motion(seq, "keypoints3d")
    moved = np.nan_to_num(kp, nan=0.0)[::-1] + np.array([0.5, 0.0, 0.0], np.float32)
    np.save(generated / f"{seq}.npy", moved[None])  # (1, F, 17, 3), as FACT-style writers do
    out = tmp_path / "gen.mp4"
    run_cli("render", str(aist_store), seq, str(out), "--generated", str(generated),
            "--stop", "120", "-q")  # fmt: skip
    got = decode(out)
    assert len(got["frames"]) == 120
    renderer = SkeletonRenderer(ds, seq, RenderOptions(stop=120, generated=(generated,)))
    assert renderer.panels[1].track.source == "generated"
    np.testing.assert_allclose(renderer.panels[1].track.positions, moved)
    check_pixels(
        got["frames"][50],
        renderer.pixels[1][50],
        renderer.panels[1].track.parents,
        renderer.layout.drawing_area(1),
    )
    # An unknown layout is one clear line naming the file.
    bad = tmp_path / "bad.npy"
    np.save(bad, np.zeros((10, 7)))
    proc = run_cli("render", str(aist_store), seq, str(out), "--generated", str(bad), "-q",
                   check=False)  # fmt: skip
    assert proc.returncode == 1 and "bad.npy" in proc.stderr and "layout" in proc.stderr


# ----------------------------------------------------------------------------- video poses


def test_video_pose2d_is_drawn_y_down(tmp_path: Path) -> None:
    from tests.ingest.test_ingest_video import generated, write_clicks

    video, poses = generated(tmp_path, 25.0, 50)
    wav = write_clicks(tmp_path / "song.wav", 120.0, 2.0)
    store = tmp_path / "store"
    run_cli("ingest", "video", str(video), "--poses", str(poses), "--store", str(store),
            "--music", str(wav), "--bpm", "120", "-q")  # fmt: skip
    ds = dancedata.open_store(store)
    out = tmp_path / "pose.mp4"
    result = render_sequence(ds, "clip", out)
    assert result.panels[0]["source"] == "pose2d" and result.panels[0]["kind"] == "image"
    got = decode(out)
    assert len(got["frames"]) == 50 and got["rate"] == 25
    assert abs(got["audio"].size / got["sr"] - 2.0) <= 1 / 25
    renderer = SkeletonRenderer(ds, "clip", RenderOptions())
    px = renderer.pixels[0][20]
    # Joint j is at y = 40 + 2 j source pixels (y down): drawn lower for higher j, not flipped.
    assert (np.diff(px[:, 1]) > 0).all()
    check_pixels(
        got["frames"][20], px, renderer.panels[0].track.parents, renderer.layout.drawing_area(0)
    )
    with pytest.raises(dancedata.errors.InputError, match="only the camera's own view"):
        SkeletonRenderer(ds, "clip", RenderOptions(view="top"))


# ----------------------------------------------------------------------------- no extra


def test_without_the_viz_extra_the_command_names_it(aist_store: Path, tmp_path: Path) -> None:
    hidden = tmp_path / "no_av"
    (hidden / "av").mkdir(parents=True)
    (hidden / "av" / "__init__.py").write_text("raise ImportError('PyAV hidden by the test')\n")
    out = tmp_path / "x.mp4"
    proc = run_cli("render", str(aist_store), first_seq(aist_store), str(out), "-q",
                   check=False, env={"PYTHONPATH": str(hidden)})  # fmt: skip
    lines = [line for line in proc.stderr.splitlines() if line.strip()]
    assert proc.returncode == 1 and len(lines) == 1
    assert "pip install 'dancedata[viz]'" in lines[0] and not out.exists()


def test_png_still_needs_no_pyav_and_is_the_frame(aist_store: Path, tmp_path: Path) -> None:
    import cv2

    hidden = tmp_path / "no_av"
    (hidden / "av").mkdir(parents=True)
    (hidden / "av" / "__init__.py").write_text("raise ImportError('PyAV hidden by the test')\n")
    seq = first_seq(aist_store)
    out = tmp_path / "still.png"
    run_cli("render", str(aist_store), seq, str(out), "--start", "241", "--view", "top", "-q",
            env={"PYTHONPATH": str(hidden)})  # fmt: skip
    image = cv2.imread(str(out))
    renderer = SkeletonRenderer(aist_store, seq, RenderOptions(view="top"))
    np.testing.assert_array_equal(image, renderer.frame(241))
    check_pixels(
        image[:, :, ::-1],
        renderer.pixels[0][241],
        renderer.styles[0].bones,
        renderer.layout.drawing_area(0),
    )


def test_generated_fact_rows_and_smpl_pickles_match_the_stored_motion(
    aist_store: Path, tmp_path: Path
) -> None:
    """FACT 225-d rows and EDGE/AIST++-style SMPL pickles of the stored motion give the SMPL
    joints of the stored motion itself (same model)."""
    import pickle

    from dancedata.viz.skeleton_source import load_generated
    from tests.featurize.test_motion_families import write_npz_model

    model = write_npz_model(tmp_path / "smpl.npz")
    ds = dancedata.open_store(aist_store)
    seq = first_seq(aist_store)
    truth = load_skeleton(ds, seq, source="smpl", smpl_model=model)
    trans, rotmat = ds.motion(seq, "trans"), ds.motion(seq, "rotmat")
    rows = np.concatenate([np.zeros((len(trans), 6)), trans, rotmat.reshape(len(trans), -1)], 1)
    np.save(tmp_path / "fact.npy", rows[None].astype(np.float32))
    scaling = 90.0
    with (tmp_path / "edge.pkl").open("wb") as f:
        pickle.dump(
            {
                "smpl_poses": ds.motion(seq, "axis_angle").reshape(len(trans), 72),
                "smpl_trans": trans * scaling,
                "smpl_scaling": np.array([scaling]),
            },
            f,
        )
    for name in ("fact.npy", "edge.pkl"):
        got = load_generated(tmp_path / name, seq, truth, smpl_model=model)
        assert got.parents == truth.parents and got.fps == truth.fps
        np.testing.assert_allclose(got.positions, truth.positions, atol=2e-4)
    # Without a model: posed about edge_smpl_offsets, like the store's own "smpl" source.
    builtin = load_skeleton(ds, seq, source="smpl")
    got = load_generated(tmp_path / "fact.npy", seq, builtin)
    np.testing.assert_allclose(got.positions, builtin.positions, atol=2e-4)


def test_coco17_figure_has_shoulder_and_hip_lines(aist_store: Path) -> None:
    """COCO-17 parents both shoulders on the nose and each hip on its shoulder: the renderer adds
    the shoulder line (5-6) and the hip line (11-12), drawn where the projection puts them."""
    from dancedata.compute.smpl import COCO17_KEYPOINTS

    seq = first_seq(aist_store)
    renderer = SkeletonRenderer(aist_store, seq, RenderOptions())
    assert renderer.panels[0].track.joints == COCO17_KEYPOINTS
    bones = {tuple(int(v) for v in b) for b in renderer.styles[0].bones}
    assert {(5, 6), (11, 12)} <= bones and len(bones) == 16 + 2
    checked = 0
    for k in range(0, renderer.n_frames, 37):
        px = renderer.pixels[0][k]
        if not np.isfinite(px[[5, 6, 11, 12]]).all():
            continue
        image = renderer.frame(k)[:, :, ::-1].astype(np.int32)  # RGB, before any encoding
        for a, b in ((5, 6), (11, 12)):
            if np.linalg.norm(px[a] - px[b]) < 12:
                continue  # seen edge-on: the line is inside the joint discs
            for t in (0.4, 0.5, 0.6):
                x, y = np.rint(px[a] + t * (px[b] - px[a])).astype(int)
                assert np.abs(image[y, x] - BG_RGB).max() > 60, (k, a, b, t)
            checked += 1
    assert checked >= 4
