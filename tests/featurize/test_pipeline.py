"""The walking skeleton end to end on a small synthetic AIST++ set: synth → ingest → featurize
→ segment → validate → loader, each checked against an independent computation."""

from __future__ import annotations

import hashlib
import pickle
from pathlib import Path

import librosa
import numpy as np
import pytest
from scipy.spatial.transform import Rotation

import dancedata
from dancedata.compute.audio_features import AudioFeatureConfig
from dancedata.featurize.featurize import FeaturizeOptions, featurize
from dancedata.featurize.segment import SegmentOptions, segment
from dancedata.ingest.aist import AistIngestOptions, ingest_aist
from dancedata.store.layout import StoreLayout
from dancedata.store.validate import validate_store
from dancedata.synth.aist import synth_aist

# slow: a 6-sequence store through featurize and segment, read by every test
pytestmark = pytest.mark.slow


@pytest.fixture(scope="module")
def built(tmp_path_factory):
    root = tmp_path_factory.mktemp("pipeline")
    raw, store = root / "raw", root / "store"
    synth_aist(raw, n_sequences=6, seed=3)
    v1 = ingest_aist(store, raw, AistIngestOptions())
    v2 = featurize(store, FeaturizeOptions())
    v3 = segment(store, SegmentOptions())
    return {"raw": raw, "store": store, "versions": (v1, v2, v3)}


def test_each_command_writes_a_new_version(built):
    names = [r.version for r in built["versions"]]
    assert names == ["v1", "v2", "v3"]
    layout = StoreLayout(built["store"])
    assert layout.committed_versions() == names
    assert layout.read_pointer()["latest"] == "v3"
    assert layout.read_manifest("v2")["parent"] == "v1"
    assert validate_store(built["store"]) == []


def test_rerun_writes_nothing_and_names_the_version(built):
    store, raw = built["store"], built["raw"]
    assert ingest_aist(store, raw, AistIngestOptions()).version == "v1"
    again = featurize(store, FeaturizeOptions(version="v1"))
    assert (again.created, again.version) == (False, "v2")
    assert segment(store, SegmentOptions()).created is False
    assert StoreLayout(store).committed_versions() == ["v1", "v2", "v3"]


def test_manifest_records_inputs_and_fingerprint(built):
    manifest = StoreLayout(built["store"]).read_manifest("v1")
    paths = {Path(i["path"]).name for i in manifest["inputs"]}
    assert "crossmodal_train.txt" in paths and any(p.endswith(".wav") for p in paths)
    for entry in manifest["inputs"]:
        assert entry["bytes"] == Path(entry["path"]).stat().st_size
        assert entry["sha256"] == hashlib.sha256(Path(entry["path"]).read_bytes()).hexdigest()
    assert len(manifest["fingerprint"]) == 64
    assert manifest["libraries"]["zarr"].startswith("3")


def test_trans_in_metres_and_axis_angle_match_the_pickles(built):
    store = dancedata.open_store(built["store"])
    for seq_id in store.seq_ids():
        with open(built["raw"] / "motions" / f"{seq_id}.pkl", "rb") as handle:
            data = pickle.load(handle)  # our own synthetic file: trusted in this test
        np.testing.assert_allclose(
            store.motion(seq_id, "trans"),
            data["smpl_trans"] / data["smpl_scaling"][0],
            rtol=1e-6,
        )
        np.testing.assert_array_equal(
            store.motion(seq_id, "axis_angle"), data["smpl_poses"].reshape(-1, 24, 3)
        )


def test_rotations_match_scipy(built):
    store = dancedata.open_store(built["store"])
    seq_id = store.seq_ids()[1]
    aa = store.motion(seq_id, "axis_angle").astype(np.float64).reshape(-1, 3)
    ref = Rotation.from_rotvec(aa)
    n = store.sequence(seq_id)["n_frames"]
    np.testing.assert_allclose(
        store.motion(seq_id, "rotmat").reshape(-1, 3, 3), ref.as_matrix(), atol=1e-6
    )
    np.testing.assert_allclose(
        store.motion(seq_id, "euler").reshape(-1, 3), ref.as_euler("XYZ"), atol=1e-5
    )
    quat = store.motion(seq_id, "quat").reshape(-1, 4).astype(np.float64)
    np.testing.assert_allclose(
        np.abs(np.sum(quat * ref.as_quat()[:, [3, 0, 1, 2]], axis=1)), 1.0, atol=1e-6
    )
    six = store.motion(seq_id, "rot6d").reshape(-1, 6)
    np.testing.assert_allclose(six[:, :3], ref.as_matrix()[:, :, 0], atol=1e-6)
    np.testing.assert_allclose(six[:, 3:], ref.as_matrix()[:, :, 1], atol=1e-6)
    assert store.motion(seq_id, "quat").shape == (n, 24, 4)


def test_quaternions_are_sign_continuous_within_each_sequence(built):
    store = dancedata.open_store(built["store"])
    for seq_id in store.seq_ids():
        quat = store.motion(seq_id, "quat").astype(np.float64)
        assert np.all(np.sum(quat[1:] * quat[:-1], axis=-1) > -1e-6)


def test_audio_features_match_librosa_called_directly(built):
    store = dancedata.open_store(built["store"])
    cfg = AudioFeatureConfig()
    music = store.music.to_pylist()[0]
    y, sr = librosa.load(music["path"], sr=30720)
    assert sr == cfg.sr == 30720
    env = librosa.onset.onset_strength(y=y, sr=sr, hop_length=512)
    mfcc = librosa.feature.mfcc(y=y, sr=sr, n_mfcc=20, hop_length=512).T
    chroma = librosa.feature.chroma_cens(y=y, sr=sr, hop_length=512).T
    peaks = librosa.onset.onset_detect(onset_envelope=env, sr=sr, hop_length=512)
    _, beats = librosa.beat.beat_track(
        onset_envelope=env, sr=sr, hop_length=512, start_bpm=music["bpm"], tightness=100
    )
    s0, s1 = music["frame_start"], music["frame_stop"]
    assert s1 - s0 == len(env) == 1 + len(y) // 512
    np.testing.assert_allclose(store.zarr("audio/onset_env")[s0:s1], env, rtol=1e-5, atol=1e-5)
    np.testing.assert_allclose(store.zarr("audio/mfcc")[s0:s1], mfcc, rtol=1e-4, atol=1e-3)
    np.testing.assert_allclose(store.zarr("audio/chroma_cens")[s0:s1], chroma, atol=1e-5)
    assert np.flatnonzero(store.zarr("audio/onset_peaks")[s0:s1]).tolist() == peaks.tolist()
    assert np.flatnonzero(store.zarr("audio/beats")[s0:s1]).tolist() == beats.tolist()
    # Beats of music synthesised at the known tempo come out at that tempo.
    period_s = np.median(np.diff(beats)) / 60.0
    assert period_s == pytest.approx(60.0 / music["bpm"], rel=0.05)


def test_audio_is_computed_once_per_track(built):
    store = dancedata.open_store(built["store"])
    n_tracks = store.music.num_rows
    assert n_tracks < store.sequences.num_rows  # some songs are shared
    assert store.zarr("audio/mfcc").shape[0] == sum(
        m["frame_stop"] - m["frame_start"] for m in store.music.to_pylist()
    )
    assert StoreLayout(built["store"]).read_manifest("v2")["counts"]["music_tracks"] == n_tracks


def test_measures_follow_the_formula(built):
    store = dancedata.open_store(built["store"])
    rows = store.measures.to_pylist()
    for seq in store.sequences.to_pylist():
        fpm = 60.0 / seq["bpm"] * 4 * seq["fps"]
        mine = [r for r in rows if r["seq_id"] == seq["seq_id"]]
        n_complete = int(np.floor((seq["n_frames"] + 0.5) / fpm + 1e-9))
        while np.floor((n_complete) * fpm + 0.5) > seq["n_frames"]:
            n_complete -= 1
        assert len(mine) == n_complete
        for k, row in enumerate(mine):
            assert row["frame_start"] == int(np.floor(k * fpm + 0.5))
            assert row["frame_stop"] == int(np.floor((k + 1) * fpm + 0.5))
            assert row["time_start"] == pytest.approx(row["frame_start"] / seq["fps"])


def test_split_counts_match_the_split_files(built):
    store = dancedata.open_store(built["store"])
    ignored = {line.strip() for line in (built["raw"] / "ignore_list.txt").read_text().splitlines()}
    for split in ("train", "val", "test"):
        listed = (built["raw"] / "splits" / f"crossmodal_{split}.txt").read_text().split()
        assert store.seq_ids(split) == [s for s in store.seq_ids() if s in set(listed) - ignored]
    assert sorted(store.seq_ids("ignored")) == sorted(ignored & set(store.seq_ids()))


def test_loader_views_and_measures(built):
    store = dancedata.open_store(built["store"])
    seq_id = store.seq_ids("train")[0]
    n = store.sequence(seq_id)["n_frames"]
    fact = store.view(seq_id, "fact_motion_225")
    assert fact.shape == (n, 225)
    np.testing.assert_array_equal(fact[:, :6], 0)
    np.testing.assert_array_equal(fact[:, 6:9], store.motion(seq_id, "trans"))
    np.testing.assert_array_equal(fact[:, 9:], store.motion(seq_id, "rotmat").reshape(n, 216))
    assert store.view(seq_id, "thesis_euler_75").shape == (n, 75)
    audio = store.view(seq_id, "fact_audio_35")
    assert audio.shape == (store.audio_frames(seq_id), 35)
    np.testing.assert_array_equal(audio[:, 0], store.audio(seq_id, "onset_env"))
    np.testing.assert_array_equal(audio[:, 33], store.audio(seq_id, "onset_peaks"))
    thesis = store.view(seq_id, "thesis_audio_22")
    np.testing.assert_array_equal(thesis[:, :20], store.audio(seq_id, "mfcc"))
    windows = list(store.iter_measures(split="train"))
    assert windows and all(w.motion.shape[0] == w.audio.shape[0] for w in windows)
    assert windows[0].genre_onehot.shape == (len(store.genres),)
    assert windows[0].genre_onehot.sum() == 1


def test_plain_zarr_and_pyarrow_read_the_store(built):
    import pyarrow.parquet as pq
    import zarr

    version = StoreLayout(built["store"]).latest()
    vdir = built["store"] / "versions" / version
    seqs = pq.read_table(vdir / "sequences.parquet").to_pylist()
    root = zarr.open_group(str(vdir / "data.zarr"), mode="r")
    first = seqs[0]
    trans = root["motion/trans"][first["frame_start"] : first["frame_stop"]]
    assert trans.shape == (first["n_frames"], 3)
    assert root["motion/quat"].attrs["quat_order"] == "wxyz"
    assert root["motion"].attrs["fps"] == 60.0


def test_same_seed_gives_identical_bytes_and_arrays(tmp_path, built):
    raw2 = tmp_path / "raw2"
    synth_aist(raw2, n_sequences=6, seed=3)
    for path in sorted(p for p in built["raw"].rglob("*") if p.is_file()):
        twin = raw2 / path.relative_to(built["raw"])
        assert twin.read_bytes() == path.read_bytes(), path
    store2 = tmp_path / "store2"
    ingest_aist(store2, raw2, AistIngestOptions())
    featurize(store2, FeaturizeOptions())
    a, b = dancedata.open_store(built["store"], "v2"), dancedata.open_store(store2)
    assert a.array_names() == b.array_names()
    for name in a.array_names():
        assert np.array_equal(a.zarr(name)[...], b.zarr(name)[...], equal_nan=True), name


def test_different_seed_gives_different_data(tmp_path):
    synth_aist(tmp_path / "a", n_sequences=3, seed=1)
    synth_aist(tmp_path / "b", n_sequences=3, seed=2)
    name = sorted((tmp_path / "a" / "motions").iterdir())[0].name
    assert (tmp_path / "a" / "motions" / name).read_bytes() != (
        tmp_path / "b" / "motions" / name
    ).read_bytes()


def test_rerunning_the_whole_chain_on_its_output_writes_nothing(built):
    store, raw = built["store"], built["raw"]
    layout = StoreLayout(store)
    before = layout.committed_versions()
    assert ingest_aist(store, raw, AistIngestOptions()).created is False
    # featurize reads only ingested data: the segmented v3 already holds its result.
    again = featurize(store, FeaturizeOptions())
    assert (again.created, again.version) == (False, "v3")
    assert segment(store, SegmentOptions()).created is False
    assert layout.committed_versions() == before
    stages = layout.read_manifest("v3")["stages"]
    assert set(stages) == {"ingest", "featurize", "segment"}
