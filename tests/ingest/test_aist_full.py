"""AIST++ in full: every annotation kind, every split scheme, any music format, selection.

Real AIST++ annotation files (../shared/data/real/aist) are paired with music generated at each
music id's tempo (AIST music cannot be redistributed). References are independent: plain
``pickle`` / ``json`` reads of the inputs, ``cv2.projectPoints``, ``soundfile``.
"""

from __future__ import annotations

import json
import pickle
import shutil
from pathlib import Path

import cv2
import numpy as np
import pytest
import soundfile as sf

import dancedata
from dancedata.io.aist_names import music_bpm
from dancedata.store.validate import validate_store
from dancedata.synth.aist import synth_aist
from dancedata.synth.music import synth_dance_music
from tests.helpers import run_cli

# slow: real public data (and a 40-sequence twin) through every command, end to end
pytestmark = pytest.mark.slow

KP2D_SEQS = ("gBR_sBM_cAll_d04_mBR2_ch08", "gBR_sBM_cAll_d06_mBR2_ch06")
AUDIO_SR, HOP = 30720, 512


def _load(path: Path) -> dict:
    with open(path, "rb") as handle:
        return pickle.load(handle)  # real AIST++ release files or our own synthetic ones


def _write_music(folder: Path, lengths_s: dict[str, float], sr: int = 22050) -> None:
    """Synthetic music at each music id's tempo, 0.025 s longer than ``lengths_s``."""
    folder.mkdir(parents=True, exist_ok=True)
    for music_id, seconds in lengths_s.items():
        y = synth_dance_music(music_bpm(music_id), seconds + 0.025, sr=sr, seed=1)
        sf.write(folder / f"{music_id}.wav", y, sr)


def _music_lengths(motions: Path) -> dict[str, float]:
    lengths: dict[str, float] = {}
    for path in motions.glob("*.pkl"):
        music_id = path.stem.split("_")[4]
        seconds = _load(path)["smpl_poses"].shape[0] / 60.0
        lengths[music_id] = max(lengths.get(music_id, 0.0), seconds)
    return lengths


def _info(store: Path) -> dict:
    return json.loads(run_cli("info", str(store), "--json").stdout)


# --------------------------------------------------------------------------------------------
# Real AIST++ annotations
# --------------------------------------------------------------------------------------------
@pytest.fixture(scope="module")
def real_store(real_data, tmp_path_factory):
    aist = real_data / "aist"
    root = tmp_path_factory.mktemp("real_aist")
    _write_music(root / "music", _music_lengths(aist / "motions"))
    store = root / "store"
    run_cli("ingest", "aist", str(aist), "--store", str(store), "--music-dir", str(root / "music"))
    return {"aist": aist, "store": store, "music": root / "music"}


@pytest.mark.real_data
def test_real_motion_and_keypoints_ingest_exactly(real_store):
    store = dancedata.open_store(real_store["store"])
    aist = real_store["aist"]
    assert sorted(store.seq_ids()) == sorted(p.stem for p in (aist / "motions").glob("*.pkl"))
    for seq_id in store.seq_ids():
        motion = _load(aist / "motions" / f"{seq_id}.pkl")
        expected = (motion["smpl_trans"] / motion["smpl_scaling"]).astype(np.float32)
        np.testing.assert_array_equal(store.motion(seq_id, "trans"), expected)
        np.testing.assert_array_equal(
            store.motion(seq_id, "axis_angle"), motion["smpl_poses"].reshape(-1, 24, 3)
        )
        kp3d = _load(aist / "keypoints3d" / f"{seq_id}.pkl")
        for key in ("keypoints3d", "keypoints3d_optim"):
            np.testing.assert_array_equal(
                store.motion(seq_id, key), (kp3d[key] / 100.0).astype(np.float32)
            )  # NaN where AIST++ has NaN (assert_array_equal treats NaN as equal)
        row = store.sequence(seq_id)
        nan_frames = int(np.isnan(kp3d["keypoints3d"]).any(axis=(1, 2)).sum())
        assert row["keypoints3d_nan_frames"] == nan_frames
        assert row["has_keypoints3d"] is True
        kp2d_path = aist / "keypoints2d" / f"{seq_id}.pkl"
        assert row["has_keypoints2d"] is kp2d_path.exists()
        if kp2d_path.exists():
            kp2d = _load(kp2d_path)
            np.testing.assert_array_equal(
                store.motion(seq_id, "keypoints2d"), np.moveaxis(kp2d["keypoints2d"], 0, 1)
            )
            np.testing.assert_array_equal(store.motion(seq_id, "det_scores"), kp2d["det_scores"].T)
        else:
            assert np.isnan(store.motion(seq_id, "keypoints2d")).all()
            assert np.isnan(store.motion(seq_id, "det_scores")).all()
    # Frame counts as docs/FORMATS.md ("Real test files") states them: three basic at 576, one
    # advanced at 1919.
    frames = sorted(store.sequence(s)["n_frames"] for s in store.seq_ids())
    assert frames == [576, 576, 576, 1919]
    assert validate_store(real_store["store"]) == []


@pytest.mark.real_data
def test_real_cameras_table_follows_the_json_and_mapping(real_store):
    store = dancedata.open_store(real_store["store"])
    cameras = real_store["aist"] / "cameras"
    mapping = dict(line.split() for line in (cameras / "mapping.txt").read_text().splitlines())
    rows = store.table("cameras").to_pylist()
    for seq_id in store.seq_ids():
        setting = store.sequence(seq_id)["camera_setting"]
        assert setting == mapping[seq_id]
        reference = json.loads((cameras / f"{setting}.json").read_text())
        mine = sorted((r for r in rows if r["setting"] == setting), key=lambda r: r["view"])
        assert [r["camera"] for r in mine] == [c["name"] for c in reference]
        for row, cam in zip(mine, reference, strict=True):
            assert (row["width"], row["height"]) == tuple(cam["size"])
            assert [row["fx"], row["cx"], row["fy"], row["cy"]] == [
                cam["matrix"][0][0],
                cam["matrix"][0][2],
                cam["matrix"][1][1],
                cam["matrix"][1][2],
            ]
            assert [row["rx"], row["ry"], row["rz"]] == cam["rotation"]
            np.testing.assert_allclose(
                [row["tx_m"], row["ty_m"], row["tz_m"]],
                np.array(cam["translation"]) / 100.0,
                rtol=1e-15,
            )
            assert [row[k] for k in ("k1", "k2", "p1", "p2", "k3")] == cam["distortions"]
    assert {r["setting"] for r in rows} == {mapping[s] for s in store.seq_ids()}


def _reprojection_px(store, seq_id: str, keypoints: str = "keypoints3d") -> np.ndarray:
    """Pixel distance (views, frames, 17) between cv2.projectPoints of the stored 3-d keypoints
    through the stored cameras and the stored 2-d detections."""
    cams = store.cameras(seq_id)
    points = store.motion(seq_id, keypoints).astype(np.float64)
    detected = store.motion(seq_id, "keypoints2d")
    errors = []
    for view in range(len(cams.names)):
        projected, _ = cv2.projectPoints(
            points.reshape(-1, 3),
            cams.rvec[view],
            cams.tvec_m[view],
            cams.intrinsics[view],
            cams.distortions[view],
        )
        projected = projected.reshape(points.shape[0], 17, 2)
        errors.append(np.linalg.norm(projected - detected[:, view, :, :2], axis=-1))
    return np.stack(errors)


@pytest.mark.real_data
@pytest.mark.parametrize("seq_id", KP2D_SEQS)
def test_real_keypoints3d_reproject_onto_keypoints2d(real_store, seq_id, capsys):
    store = dancedata.open_store(real_store["store"])
    errors = _reprojection_px(store, seq_id)
    optim = _reprojection_px(store, seq_id, "keypoints3d_optim")
    median, median_optim = float(np.nanmedian(errors)), float(np.nanmedian(optim))
    with capsys.disabled():
        print(
            f"\n{seq_id}: median reprojection error {median:.2f} px (keypoints3d), "
            f"{median_optim:.2f} px (keypoints3d_optim); per view "
            f"{np.round(np.nanmedian(errors.reshape(9, -1), axis=1), 1).tolist()}"
        )
    # Detector noise on 1920×1080 frames of a person ~500 px tall: a few pixels.
    assert median < 15.0 and median_optim < 15.0
    assert np.nanpercentile(errors, 90) < 60.0


@pytest.mark.real_data
def test_real_camera_translation_is_in_cm_like_keypoints3d(real_store):
    """Projection is invariant to a common scale of points and translation, so cm with cm and
    m with m agree exactly; mixing units is far off. That is how we know the JSON is in cm."""
    aist = real_store["aist"]
    seq_id = KP2D_SEQS[0]
    cams = json.loads((aist / "cameras" / "setting1.json").read_text())
    points_cm = _load(aist / "keypoints3d" / f"{seq_id}.pkl")["keypoints3d_optim"].reshape(-1, 3)
    detected = _load(aist / "keypoints2d" / f"{seq_id}.pkl")["keypoints2d"][0, :, :, :2]
    cam = {k: np.array(cams[0][k], dtype=np.float64) for k in cams[0] if k not in ("name",)}

    def project(points, translation):
        uv, _ = cv2.projectPoints(
            points, cam["rotation"], translation, cam["matrix"], cam["distortions"]
        )
        return uv.reshape(-1, 17, 2)

    cm_cm = project(points_cm, cam["translation"])
    m_m = project(points_cm / 100.0, cam["translation"] / 100.0)
    m_cm = project(points_cm / 100.0, cam["translation"])
    np.testing.assert_allclose(m_m, cm_cm, atol=1e-6)
    assert np.nanmedian(np.linalg.norm(cm_cm - detected, axis=-1)) < 15.0
    assert np.nanmedian(np.linalg.norm(m_cm - detected, axis=-1)) > 100.0


@pytest.mark.real_data
def test_loader_projection_matrices_are_k_r_t(real_store):
    store = dancedata.open_store(real_store["store"])
    seq_id = KP2D_SEQS[1]
    cams = store.cameras(seq_id)
    matrices = store.projection_matrices(seq_id)
    assert matrices.shape == (9, 3, 4)
    points = store.motion(seq_id, "keypoints3d_optim").astype(np.float64).reshape(-1, 3)
    homogeneous = np.concatenate([points, np.ones((points.shape[0], 1))], axis=1)
    for view in range(9):
        rotation, _ = cv2.Rodrigues(cams.rvec[view])
        expected = cams.intrinsics[view] @ np.hstack([rotation, cams.tvec_m[view][:, None]])
        np.testing.assert_allclose(matrices[view], expected, rtol=1e-12, atol=1e-9)
        # Undistorted pinhole: P [X; 1] equals cv2.projectPoints with zero distortion.
        pixels = homogeneous @ matrices[view].T
        pixels = pixels[:, :2] / pixels[:, 2:]
        reference, _ = cv2.projectPoints(
            points, cams.rvec[view], cams.tvec_m[view], cams.intrinsics[view], np.zeros(5)
        )
        np.testing.assert_allclose(pixels, reference.reshape(-1, 2), atol=1e-6)


@pytest.mark.real_data
def test_real_split_counts_via_info_json(real_store):
    info = _info(real_store["store"])
    files = info["split_files"]
    assert files["ignore_list"] == 45
    assert files["ignore_list_in_store"] == 0
    train = files["schemes"]["crossmodal"]["train"]
    assert (train["listed"], train["ignored"], train["usable"]) == (980, 28, 952)
    assert (train["in_store"], train["missing_from_store"]) == (4, 976)
    test = files["schemes"]["crossmodal"]["test"]
    assert (test["listed"], test["usable"], test["in_store"]) == (20, 20, 0)
    assert info["splits_in_store"] == {"crossmodal": {"train": 4}}
    assert info["annotations_missing"] == {
        "keypoints3d": 0,
        "keypoints2d": 2,
        "cameras": 0,
        "music": 0,
    }
    text = run_cli("info", str(real_store["store"])).stdout
    assert "missing   keypoints2d for 2 of 4 sequences" in text
    assert "crossmodal/train: 980 listed, 28 ignored, 952 usable, 4 in store" in text


# --------------------------------------------------------------------------------------------
# Synthetic AIST++: missing annotations, splits, music formats, selection
# --------------------------------------------------------------------------------------------
@pytest.fixture(scope="module")
def synth40(tmp_path_factory):
    """40 sequences: 4 per genre over all 10 genres."""
    raw = tmp_path_factory.mktemp("synth40") / "raw"
    synth_aist(raw, n_sequences=40, seed=5)
    return raw


def test_synthetic_keypoints2d_are_keypoints3d_seen_by_the_cameras(synth40, tmp_path):
    store = tmp_path / "store"
    run_cli("ingest", "aist", str(synth40), "--store", str(store), "-q", "--genres", "gWA")
    opened = dancedata.open_store(store)
    for seq_id in opened.seq_ids():
        errors = _reprojection_px(opened, seq_id, "keypoints3d_optim")
        # 1.5 px Gaussian detector noise per axis: Rayleigh median 1.5 × 1.1774 = 1.77 px.
        assert float(np.nanmedian(errors)) == pytest.approx(1.77, rel=0.1)
    assert validate_store(store) == []


def test_every_array_matches_the_pickles_across_chunk_boundaries(synth40, tmp_path):
    """40 sequences span five 8192-frame chunks, written several chunks per call."""
    store = tmp_path / "store"
    run_cli("ingest", "aist", str(synth40), "--store", str(store), "-q", "--workers", "2")
    opened = dancedata.open_store(store)
    assert opened.sequences.column("frame_stop").to_pylist()[-1] > 4 * 8192
    for seq_id in opened.seq_ids():
        motion = _load(synth40 / "motions" / f"{seq_id}.pkl")
        kp3d = _load(synth40 / "keypoints3d" / f"{seq_id}.pkl")
        kp2d = _load(synth40 / "keypoints2d" / f"{seq_id}.pkl")
        expected = {
            "trans": (motion["smpl_trans"] / motion["smpl_scaling"]).astype(np.float32),
            "axis_angle": motion["smpl_poses"].reshape(-1, 24, 3),
            "keypoints3d": (kp3d["keypoints3d"] / 100.0).astype(np.float32),
            "keypoints3d_optim": (kp3d["keypoints3d_optim"] / 100.0).astype(np.float32),
            "keypoints2d": np.moveaxis(kp2d["keypoints2d"], 0, 1),
            "det_scores": kp2d["det_scores"].T,
        }
        for name, values in expected.items():
            np.testing.assert_array_equal(opened.motion(seq_id, name), values, err_msg=name)
    assert validate_store(store) == []


def test_missing_annotation_kinds_are_nan_rows_and_reported(tmp_path):
    raw, store = tmp_path / "raw", tmp_path / "store"
    synth_aist(raw, n_sequences=6, seed=2)
    names = sorted(p.stem for p in (raw / "motions").glob("*.pkl"))
    (raw / "keypoints2d" / f"{names[0]}.pkl").unlink()
    (raw / "keypoints2d" / f"{names[1]}.pkl").unlink()
    (raw / "keypoints3d" / f"{names[2]}.pkl").unlink()
    mapping = raw / "cameras" / "mapping.txt"
    lines = [line for line in mapping.read_text().splitlines() if not line.startswith(names[3])]
    mapping.write_text("\n".join(lines) + "\n")
    run_cli("ingest", "aist", str(raw), "--store", str(store), "-q")
    opened = dancedata.open_store(store)
    for seq_id in names:
        row = opened.sequence(seq_id)
        assert row["has_keypoints2d"] is (seq_id not in names[:2])
        assert row["has_keypoints3d"] is (seq_id != names[2])
        assert (row["camera_setting"] is None) is (seq_id == names[3])
        kp2d = opened.motion(seq_id, "keypoints2d")
        kp3d = opened.motion(seq_id, "keypoints3d_optim")
        assert kp2d.shape == (row["n_frames"], 9, 17, 3) and kp3d.shape == (row["n_frames"], 17, 3)
        assert np.isnan(kp2d).all() == (not row["has_keypoints2d"])
        assert np.isnan(kp3d).all() == (not row["has_keypoints3d"])
    info = _info(store)
    assert info["annotations_missing"] == {
        "keypoints3d": 1,
        "keypoints2d": 2,
        "cameras": 1,
        "music": 0,
    }
    text = run_cli("info", str(store)).stdout
    assert "missing   keypoints2d for 2 of 6 sequences" in text
    assert "missing   cameras for 1 of 6 sequences" in text
    assert validate_store(store) == []
    # Choosing kinds at ingest: none at all gives no keypoint arrays and no cameras table.
    bare = tmp_path / "bare"
    run_cli("ingest", "aist", str(raw), "--store", str(bare), "-q", "--annotations", "")
    bare_store = dancedata.open_store(bare)
    assert not [n for n in bare_store.array_names() if "keypoints" in n]
    assert bare_store.sequence(names[5])["camera_setting"] is None


def test_keypoints_longer_than_the_motion_fail_clearly(tmp_path):
    raw, store = tmp_path / "raw", tmp_path / "store"
    synth_aist(raw, n_sequences=3, seed=4)
    bad = sorted((raw / "keypoints3d").iterdir())[0]
    data = _load(bad)
    data = {k: np.concatenate([v, v[:5]]) for k, v in data.items()}
    bad.write_bytes(pickle.dumps(data))
    proc = run_cli("ingest", "aist", str(raw), "--store", str(store), "-q", check=False)
    assert proc.returncode == 1
    lines = [line for line in proc.stderr.splitlines() if line.strip()]
    assert len(lines) == 1 and bad.name in lines[0] and "keypoints3d has" in lines[0]
    proc = run_cli(
        "ingest", "aist", str(raw), "--store", str(store), "-q", "--on-error", "skip", "--json"
    )
    summary = json.loads(proc.stdout)
    assert summary["counts"]["sequences"] == 2
    assert [s["path"] for s in summary["skipped"]] == [str(bad)]


def test_every_split_scheme_is_counted(synth40, tmp_path):
    store = tmp_path / "store"
    run_cli(
        "ingest", "aist", str(synth40), "--store", str(store), "-q", "--annotations", ""
    )  # splits do not need keypoints: keep this test fast
    info = _info(store)
    ignored = {line.strip() for line in (synth40 / "ignore_list.txt").read_text().splitlines()}
    assert info["split_files"]["ignore_list"] == len(ignored)
    assert info["split_files"]["ignore_list_in_store"] == len(ignored)
    opened = dancedata.open_store(store)
    for scheme in ("crossmodal", "pose"):
        for split in ("train", "val", "test"):
            listed = (synth40 / "splits" / f"{scheme}_{split}.txt").read_text().split()
            counts = info["split_files"]["schemes"][scheme][split]
            assert counts["listed"] == len(listed)
            assert counts["ignored"] == len(set(listed) & ignored)
            assert counts["usable_in_store"] == len(set(listed) - ignored)
            assert opened.seq_ids(split, scheme=scheme) == [
                s for s in opened.seq_ids() if s in set(listed) - ignored
            ]


@pytest.mark.parametrize(
    ("fmt", "sr", "channels"), [("wav", 44100, 2), ("mp3", 22050, 1), ("flac", 48000, 2)]
)
def test_music_in_any_format_rate_and_channel_count(tmp_path, fmt, sr, channels):
    raw, store = tmp_path / "raw", tmp_path / "store"
    synth_aist(raw, n_sequences=3, seed=6)
    music = tmp_path / "music"
    music.mkdir()
    lengths = _music_lengths(raw / "motions")
    for music_id, seconds in lengths.items():
        mono = synth_dance_music(music_bpm(music_id), seconds + 0.025, sr=sr, seed=2)
        samples = np.stack([mono] * channels, axis=1) if channels > 1 else mono
        sf.write(music / f"{music_id}.{fmt}", samples, sr, format=fmt.upper())
    run_cli(
        "ingest", "aist", str(raw), "--store", str(store), "-q", "--music-dir", str(music),
        "--annotations", "",
    )  # fmt: skip
    opened = dancedata.open_store(store)
    tracks = {m["music_id"]: m for m in opened.music.to_pylist()}
    assert set(tracks) == set(lengths)
    for music_id, track in tracks.items():
        path = music / f"{music_id}.{fmt}"
        decoded, decoded_sr = sf.read(path, always_2d=True)
        assert (track["sr"], track["channels"]) == (decoded_sr, channels) == (sr, channels)
        assert track["n_samples"] == decoded.shape[0]
        n_frames = 1 + int(np.ceil(decoded.shape[0] * AUDIO_SR / sr)) // HOP
        assert track["frame_stop"] - track["frame_start"] == n_frames
    for seq in opened.sequences.to_pylist():
        track = tracks[seq["music_id"]]
        available = track["frame_stop"] - track["frame_start"]
        assert seq["audio_frames"] == min(seq["n_frames"], available)
        assert seq["audio_truncated_frames"] == max(0, available - seq["n_frames"])
        if seq["n_frames"] / 60.0 == pytest.approx(lengths[seq["music_id"]]):
            # The longest sequence of each song: features run 1–2 frames past the motion.
            assert seq["audio_truncated_frames"] in (1, 2)


def test_missing_music_is_a_clear_error_unless_allowed(tmp_path):
    raw, store = tmp_path / "raw", tmp_path / "store"
    synth_aist(raw, n_sequences=4, seed=7)
    gone = sorted((raw / "wav").iterdir())[0]
    gone.unlink()
    proc = run_cli("ingest", "aist", str(raw), "--store", str(store), "-q", check=False)
    assert proc.returncode == 1
    lines = [line for line in proc.stderr.splitlines() if line.strip()]
    assert len(lines) == 1 and gone.stem in lines[0] and "--allow-missing-music" in lines[0]
    assert str(raw / "wav") in lines[0]
    run_cli(
        "ingest", "aist", str(raw), "--store", str(store), "-q", "--allow-missing-music",
        "--annotations", "",
    )  # fmt: skip
    opened = dancedata.open_store(store)
    without = [s for s in opened.sequences.to_pylist() if s["music_id"] == gone.stem]
    assert without and all(s["music_missing"] and s["audio_frames"] == 0 for s in without)
    assert gone.stem not in {m["music_id"] for m in opened.music.to_pylist()}
    info = _info(store)
    assert info["music_missing"] == len(without) == info["annotations_missing"]["music"]
    assert validate_store(store) == []


def test_music_much_shorter_than_the_motion_fails_clearly(tmp_path):
    raw, store = tmp_path / "raw", tmp_path / "store"
    synth_aist(raw, n_sequences=3, seed=8)
    short = sorted((raw / "wav").iterdir())[0]
    sf.write(short, synth_dance_music(100.0, 1.0, sr=24000), 24000)
    proc = run_cli(
        "ingest", "aist", str(raw), "--store", str(store), "-q", "--annotations", "", check=False
    )
    assert proc.returncode == 1
    lines = [line for line in proc.stderr.splitlines() if line.strip()]
    assert len(lines) == 1
    assert f"music {short.stem} gives 61 feature frames (1.02 s) but the motion has" in lines[0]
    assert "/motions/" in lines[0] and short.stem in lines[0]


def test_genre_and_situation_selection(synth40, tmp_path):
    def ingest(name: str, *options: str) -> dancedata.DanceStore:
        store = tmp_path / name
        run_cli(
            "ingest", "aist", str(synth40), "--store", str(store), "-q", "--annotations", "",
            *options,
        )  # fmt: skip
        return dancedata.open_store(store)

    everything = ingest("all")
    assert len(everything.genres) == 10
    assert everything.genre_onehot(everything.seq_ids()[0]).shape == (10,)
    no_jb = ingest("no-jb", "--exclude-genres", "gJB")
    assert "gJB" not in no_jb.genres and len(no_jb.genres) == 9
    for seq_id in no_jb.seq_ids():
        onehot = no_jb.genre_onehot(seq_id)
        assert onehot.shape == (9,) and onehot.sum() == 1
        assert no_jb.genres[int(np.argmax(onehot))] == no_jb.sequence(seq_id)["genre"]
    two = ingest("two", "--genres", "gBR,gPO")
    assert two.genres == ["gBR", "gPO"] and two.genre_onehot(two.seq_ids()[0]).shape == (2,)
    advanced = ingest("sfm", "--situations", "sFM")
    situations = {advanced.sequence(s)["situation"] for s in advanced.seq_ids()}
    assert situations == {"sFM"} and len(advanced.seq_ids()) == 10
    # Split counts still come from the files: listed names outside the selection are skipped.
    files = _info(tmp_path / "two")["split_files"]["schemes"]["crossmodal"]["train"]
    listed = (synth40 / "splits" / "crossmodal_train.txt").read_text().split()
    assert files["listed"] == len(listed)
    assert files["in_store"] == sum(n.startswith(("gBR", "gPO")) for n in listed)
    assert files["missing_from_store"] == files["listed"] - files["in_store"]
    # A code that names no genre is an error, not an empty selection.
    proc = run_cli(
        "ingest", "aist", str(synth40), "--store", str(tmp_path / "x"), "--genres", "gXX",
        check=False,
    )  # fmt: skip
    assert proc.returncode == 1 and "--genres: unknown ['gXX']" in proc.stderr


def test_cameras_of_a_store_are_usable_without_dancedata(synth40, tmp_path):
    """Plain pyarrow: one row per (setting, camera) is enough to build OpenCV cameras."""
    import pyarrow.parquet as pq

    store = tmp_path / "store"
    run_cli("ingest", "aist", str(synth40), "--store", str(store), "-q", "--genres", "gKR")
    version = store / "versions" / "v1"
    cameras = pq.read_table(version / "cameras.parquet").to_pylist()
    sequences = pq.read_table(version / "sequences.parquet").to_pylist()
    setting = sequences[0]["camera_setting"]
    raw = json.loads((synth40 / "cameras" / f"{setting}.json").read_text())
    mine = sorted((c for c in cameras if c["setting"] == setting), key=lambda c: c["view"])
    for row, cam in zip(mine, raw, strict=True):
        intrinsics = np.array(
            [[row["fx"], row["skew"], row["cx"]], [0, row["fy"], row["cy"]], [0, 0, 1]]
        )
        np.testing.assert_allclose(intrinsics, cam["matrix"])
        np.testing.assert_allclose(
            [row["tx_m"], row["ty_m"], row["tz_m"]], np.array(cam["translation"]) / 100
        )
    shutil.rmtree(store)


def test_bad_camera_file_fails_clearly_or_is_skipped(tmp_path):
    raw, store = tmp_path / "raw", tmp_path / "store"
    synth_aist(raw, n_sequences=3, seed=9)
    bad = sorted((raw / "cameras").glob("setting*.json"))[0]
    cameras = json.loads(bad.read_text())
    del cameras[2]["rotation"]
    bad.write_text(json.dumps(cameras))
    proc = run_cli("ingest", "aist", str(raw), "--store", str(store), "-q", check=False)
    assert proc.returncode == 1
    lines = [line for line in proc.stderr.splitlines() if line.strip()]
    assert len(lines) == 1 and str(bad) in lines[0] and "camera c03 lacks ['rotation']" in lines[0]
    summary = json.loads(
        run_cli(
            "ingest", "aist", str(raw), "--store", str(store), "-q", "--on-error", "skip",
            "--json",
        ).stdout
    )  # fmt: skip
    assert [s["path"] for s in summary["skipped"]] == [str(bad)]
    opened = dancedata.open_store(store)
    lacking = [s for s in opened.seq_ids() if opened.sequence(s)["camera_setting"] is None]
    assert lacking and summary["counts"]["annotations_missing"]["cameras"] == len(lacking)
