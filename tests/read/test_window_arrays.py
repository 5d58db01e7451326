"""Training windows over any stored arrays, per beat and per phrase, normalised and augmented.

Two real stores: the real CMU BVH 01_01.bvh with the real Vibe Ace track (ingested at 30 fps,
quaternions and STFT frames featurized, beats and phrases segmented) and a synthetic AIST++
store built by the real pipeline (synth → ingest → featurize → segment → stats). Every window
is checked against the zarr arrays sliced by hand (brute force), spans against the segment
tables, resampling against scipy's Slerp and np.interp, normalisation against the stats table
and against pooled np.mean / np.std, augmentation against closed forms.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from scipy.spatial.transform import Rotation, Slerp

import dancedata
from dancedata.compute.rotations import rot6d_to_rotmat
from dancedata.errors import InputError, StoreError
from dancedata.read.window_augment import Mirror, Yaw, mirror_rows, yaw_rows
from dancedata.read.window_dataset import store_rig
from tests.helpers import run_cli

torch = pytest.importorskip("torch")

from dancedata.read.torch_batching import training_loader  # noqa: E402
from dancedata.read.torch_data import (  # noqa: E402
    BeatDataset,
    MeasureDataset,
    PhraseDataset,
    SecondsDataset,
)

MOTION = ["motion/quat", "motion/trans"]
AUDIO = "audio/stft_frames"


@pytest.fixture(scope="module")
def aist_store(tmp_path_factory) -> Path:
    from dancedata.featurize.family_settings import AudioSettings
    from dancedata.featurize.featurize import FeaturizeOptions, featurize
    from dancedata.featurize.segment import SegmentOptions, segment
    from dancedata.featurize.stats import StatsOptions, stats
    from dancedata.ingest.aist import AistIngestOptions, ingest_aist
    from dancedata.synth.aist import synth_aist

    root = tmp_path_factory.mktemp("window-arrays")
    synth_aist(root / "raw", n_sequences=4, seed=0)
    path = root / "store"
    ingest_aist(path, root / "raw", AistIngestOptions())
    featurize(
        path,
        FeaturizeOptions(
            representations=["rotmat", "euler", "quat", "rot6d"],
            motion_families=["rotations", "positions"],
            audio_families=["fact", "stft_frames"],
            audio_settings=AudioSettings(stems="none"),
        ),
    )
    segment(path, SegmentOptions(tables=("measures", "beats", "phrases")))
    arrays = ["motion/quat", "motion/trans", "motion/rotmat", "audio/mfcc", "audio/stft_frames"]
    stats(path, StatsOptions(arrays=arrays))
    return path


@pytest.fixture(scope="module")
def bvh_store(real_data: Path, tmp_path_factory) -> Path:
    path = tmp_path_factory.mktemp("window-bvh") / "store"
    music = real_data / "audio" / "Kevin_MacLeod_-_Vibe_Ace.hq.ogg"
    run_cli(
        "ingest", "bvh", str(real_data / "bvh" / "01_01.bvh"), "--store", str(path),
        "--units", "0.056444", "--fps", "30", "--music", str(music), "--bpm", "120", "-q",
    )  # fmt: skip
    run_cli(
        "featurize", str(path), "--representations", "rotmat,quat",
        "--audio-families", "fact,stft_frames", "--stems", "none", "-q",
    )  # fmt: skip
    run_cli("segment", str(path), "--tables", "measures,beats,phrases", "-q")
    return path


def _stores(request) -> tuple[Path, str | None]:
    """(store, split) of the parametrised store."""
    if request.param == "bvh":
        return request.getfixturevalue("bvh_store"), None
    return request.getfixturevalue("aist_store"), "train"


@pytest.fixture(params=["bvh", "aist"])
def any_store(request) -> tuple[Path, str | None]:
    if request.param == "bvh":
        request.applymarker(pytest.mark.real_data)
    return _stores(request)


def _brute_force(opened, seq_id: str, start: int, length: int, names, group: str) -> np.ndarray:
    """The arrays sliced straight from zarr, flattened and put side by side."""
    row = opened.sequence(seq_id)
    base = int(row["frame_start"]) if group == "motion" else opened.audio_start(seq_id)
    cols = []
    for name in [names] if isinstance(names, str) else names:
        block = np.asarray(opened.zarr(name)[base + start : base + start + length])
        cols.append(block.reshape(length, -1).astype(np.float32))
    return np.concatenate(cols, axis=1)


# ------------------------------------------------------------------- any arrays, any store


@pytest.mark.slow
def test_quaternions_and_stft_per_measure_window_equal_the_arrays_sliced(any_store) -> None:
    path, split = any_store
    opened = dancedata.open_store(path)
    ds = MeasureDataset(path, split=split, motion=MOTION, audio=AUDIO)
    joints = opened.zarr("motion/quat").shape[1]
    k = opened.zarr(AUDIO).shape[2]
    rows = [
        r for r in opened.measure_rows(split) if r["frame_stop"] <= opened.audio_frames(r["seq_id"])
    ]
    assert len(ds) == len(rows) > 0
    for i, r in enumerate(rows):
        item = ds[i]
        n = r["frame_stop"] - r["frame_start"]
        assert (item["seq_id"], item["measure"], item["frame_start"]) == (
            r["seq_id"], r["measure"], r["frame_start"],
        )  # fmt: skip
        assert item["motion"].shape == (n, 4 * joints + 3)
        assert item["audio"].shape == (n, 1025 * k)
        want = _brute_force(opened, r["seq_id"], r["frame_start"], n, MOTION, "motion")
        np.testing.assert_array_equal(item["motion"].numpy(), want)
        want = _brute_force(opened, r["seq_id"], r["frame_start"], n, AUDIO, "audio")
        np.testing.assert_array_equal(item["audio"].numpy(), want)
    cols = ds.columns
    assert [(p.name, p.start, p.stop, p.shape) for p in cols["motion"]] == [
        ("motion/quat", 0, 4 * joints, (joints, 4)),
        ("motion/trans", 4 * joints, 4 * joints + 3, (3,)),
    ]
    assert [(p.name, p.method, p.shape) for p in cols["audio"]] == [(AUDIO, "linear", (1025, k))]
    assert cols["motion"][0].method == "slerp_quat"


@pytest.mark.slow
def test_quaternions_and_stft_per_seconds_window_equal_the_arrays_sliced(any_store) -> None:
    path, split = any_store
    opened = dancedata.open_store(path)
    ds = SecondsDataset(path, split=split, seconds=2.0, hop_seconds=0.5, motion=MOTION, audio=AUDIO)
    expected = []
    for seq_id in opened.seq_ids(split):
        fps = float(opened.sequence(seq_id)["fps"])
        window, hop = round(2.0 * fps), 0.5 * fps
        available = min(int(opened.sequence(seq_id)["n_frames"]), opened.audio_frames(seq_id))
        k = 0
        while int(np.floor(k * hop + 0.5)) + window <= available:
            expected.append((seq_id, int(np.floor(k * hop + 0.5)), window))
            k += 1
    assert len(ds) == len(expected) > 0
    for i in (0, len(ds) // 2, len(ds) - 1):
        seq_id, start, n = expected[i]
        item = ds[i]
        assert (item["seq_id"], item["frame_start"], item["length"]) == (seq_id, start, n)
        want = _brute_force(opened, seq_id, start, n, MOTION, "motion")
        np.testing.assert_array_equal(item["motion"].numpy(), want)
        want = _brute_force(opened, seq_id, start, n, AUDIO, "audio")
        np.testing.assert_array_equal(item["audio"].numpy(), want)


@pytest.mark.slow
def test_resampled_array_windows_slerp_quaternions_and_interpolate_stft(any_store) -> None:
    path, split = any_store
    opened = dancedata.open_store(path)
    spec = ["motion/quat", "motion/rotmat", "motion/trans"]
    ds = MeasureDataset(path, split=split, motion=spec, audio=AUDIO, window_frames=40)
    plain = MeasureDataset(path, split=split, motion=spec, audio=AUDIO)
    raw, item = plain[1], ds[1]
    n, joints = raw["motion"].shape[0], opened.zarr("motion/quat").shape[1]
    t = np.arange(40) * (n - 1) / 39
    quat = raw["motion"][:, : 4 * joints].numpy().reshape(n, joints, 4).astype(np.float64)
    got = item["motion"][:, : 4 * joints].numpy().reshape(40, joints, 4)
    for j in (0, joints // 2, joints - 1):
        slerp = Slerp(np.arange(n), Rotation.from_quat(quat[:, j][:, [1, 2, 3, 0]]))
        want = slerp(t).as_matrix()
        have = Rotation.from_quat(got[:, j][:, [1, 2, 3, 0]].astype(np.float64)).as_matrix()
        np.testing.assert_allclose(have, want, atol=2e-6)
    rot = item["motion"][:, 4 * joints : 13 * joints].numpy().reshape(40, joints, 3, 3)
    np.testing.assert_allclose(  # the rotmat part and the quat part give one rotation
        rot,
        Rotation.from_quat(got.reshape(-1, 4)[:, [1, 2, 3, 0]]).as_matrix().reshape(rot.shape),
        atol=2e-6,
    )
    audio = raw["audio"].numpy()
    for c in (0, 500, audio.shape[1] - 1):
        np.testing.assert_allclose(
            item["audio"][:, c].numpy(),
            np.interp(t, np.arange(n), audio[:, c]),
            rtol=1e-5,
            atol=1e-6,
        )


@pytest.mark.slow
@pytest.mark.real_data
def test_a_paper_view_that_does_not_fit_the_rig_is_refused_with_the_reason(bvh_store) -> None:
    with pytest.raises(StoreError, match=r"24-joint SMPL rig.*31 joints.*288 columns, not 225"):
        MeasureDataset(bvh_store, motion="fact_motion_225", audio=None)
    with pytest.raises(StoreError, match=r"thesis_euler_75.*31 joints"):
        dancedata.open_store(bvh_store).view("01_01", "thesis_euler_75")
    with pytest.raises(StoreError, match=r"unknown view 'quat'.*array path such as motion/quat"):
        MeasureDataset(bvh_store, motion="quat", audio=None)
    with pytest.raises(
        StoreError, match=r"motion= takes motion views.*put audio/ arrays in audio="
    ):
        MeasureDataset(bvh_store, motion=["motion/quat", "audio/mel96"], audio=None)
    with pytest.raises(StoreError, match=r"motion/velocity.*lacks.*featurize --help"):
        MeasureDataset(bvh_store, motion="motion/velocity", audio=None)
    with pytest.raises(StoreError, match="unknown view"):
        MeasureDataset(bvh_store, motion="motion/../store.json", audio=None)
    # the audio layout fits (its width does not depend on the rig)
    assert MeasureDataset(bvh_store, motion=None)[0]["audio"].shape[1] == 35


@pytest.mark.slow
def test_array_windows_through_workers_equal_the_in_process_batches(aist_store) -> None:
    ds = MeasureDataset(
        aist_store, split="train", motion=MOTION, audio=AUDIO, n_measures=2, hop_measures=1
    )
    ref = [b for b in training_loader(ds, 3, seed=5, bucket=True)]
    got = [b for b in training_loader(ds, 3, seed=5, bucket=True, num_workers=2)]
    assert len(ref) == len(got) > 1
    for a, b in zip(ref, got, strict=True):
        assert a["seq_id"] == b["seq_id"]
        for key in ("motion", "audio", "mask", "lengths", "frame_start"):
            assert torch.equal(a[key], b[key])


# ---------------------------------------------------------------------- beats and phrases


@pytest.mark.slow
def test_beat_windows_are_the_beats_table_spans(any_store) -> None:
    path, split = any_store
    opened = dancedata.open_store(path)
    wanted = set(opened.seq_ids(split))
    beats = [r for r in opened.table("beats").to_pylist() if r["seq_id"] in wanted]
    expected = []  # brute force: n=2 consecutive beats, hop 1, closed by the beat after them
    for seq_id in dict.fromkeys(r["seq_id"] for r in beats):
        mine = sorted((r for r in beats if r["seq_id"] == seq_id), key=lambda r: r["beat"])
        for a in range(len(mine) - 2):
            stop = mine[a + 2]["frame"]
            if stop <= opened.audio_frames(seq_id):
                expected.append(
                    (seq_id, mine[a]["beat"], mine[a]["measure"], mine[a]["frame"], stop)
                )
    ds = BeatDataset(path, split=split, motion=MOTION, audio=AUDIO, n_beats=2, hop_beats=1)
    assert len(ds) == len(expected) > 0
    for i, (seq_id, beat, _measure, start, stop) in enumerate(expected):
        span = (ds.source.spans.seq_ids[i], int(ds.source.spans.unit[i]))
        assert span == (seq_id, beat)
        assert int(ds.lengths[i]) == stop - start
    for i in (0, len(ds) - 1):
        seq_id, beat, measure, start, stop = expected[i]
        item = ds[i]
        assert (item["beat"], item["measure"], item["frame_start"]) == (beat, measure, start)
        want = _brute_force(opened, seq_id, start, stop - start, MOTION, "motion")
        np.testing.assert_array_equal(item["motion"].numpy(), want)
    batch = ds.batch([0, 1])
    assert batch["beat"].tolist() == [expected[0][1], expected[1][1]]


@pytest.mark.slow
def test_phrase_windows_are_the_phrases_table_rows(any_store) -> None:
    path, split = any_store
    opened = dancedata.open_store(path)
    wanted = set(opened.seq_ids(split))
    rows = [
        r for r in opened.table("phrases").to_pylist()
        if r["seq_id"] in wanted and r["frame_stop"] <= opened.audio_frames(r["seq_id"])
    ]  # fmt: skip
    ds = PhraseDataset(path, split=split, motion=MOTION, audio=AUDIO)
    assert len(ds) == len(rows) > 0
    for i, r in enumerate(rows):
        item = ds[i]
        assert (item["seq_id"], item["phrase"], item["measure"], item["frame_start"]) == (
            r["seq_id"], r["phrase"], r["measure_start"], r["frame_start"],
        )  # fmt: skip
        n = r["frame_stop"] - r["frame_start"]
        want = _brute_force(opened, r["seq_id"], r["frame_start"], n, AUDIO, "audio")
        np.testing.assert_array_equal(item["audio"].numpy(), want)
    fixed = PhraseDataset(path, split=split, motion=MOTION, audio=None, window_frames=64)
    assert fixed[0]["motion"].shape == (64, ds[0]["motion"].shape[1])


@pytest.mark.slow
def test_a_store_without_the_unit_table_names_the_segment_command(aist_store) -> None:
    with pytest.raises(
        StoreError, match=r"no beats table.*dancedata segment .* --tables measures,beats"
    ):
        BeatDataset(aist_store, split="train", version="v2")
    with pytest.raises(StoreError, match=r"no phrases table.*--tables measures,phrases"):
        PhraseDataset(aist_store, split="train", version="v2")


# ----------------------------------------------------------------------------- normalising


@pytest.mark.slow
def test_normalised_train_frames_have_mean_0_and_std_1_per_column(aist_store) -> None:
    opened = dancedata.open_store(aist_store)
    fps = float(opened.sequence(opened.seq_ids("train")[0])["fps"])
    one = {"seconds": 1 / fps, "hop_seconds": 1 / fps, "normalize": True}
    motion = SecondsDataset(aist_store, split="train", motion=MOTION, audio=None, **one)
    audio = SecondsDataset(aist_store, split="train", motion=None, audio="audio/mfcc", **one)
    n_frames = sum(int(opened.sequence(s)["n_frames"]) for s in opened.seq_ids("train"))
    assert len(motion) == n_frames  # one-frame windows: every train frame once
    for ds, key in ((motion, "motion"), (audio, "audio")):
        x = np.concatenate([ds.source.item(i)[key] for i in range(len(ds))]).astype(np.float64)
        _, std = ds.normalization(key)
        varying = std > 1e-6
        np.testing.assert_allclose(x.mean(axis=0), 0.0, atol=2e-4)
        np.testing.assert_allclose(x.std(axis=0)[varying], 1.0, atol=2e-4)
        np.testing.assert_array_equal(x[:, ~varying], 0.0)
    # against the arrays themselves: the table's mean is np.mean over the train frames
    quat = np.concatenate([opened.motion(s, "quat") for s in opened.seq_ids("train")])
    quat = quat.astype(np.float64)
    mean, std = motion.normalization("motion")
    np.testing.assert_allclose(mean[: quat[0].size], quat.reshape(len(quat), -1).mean(0), atol=1e-6)
    np.testing.assert_allclose(std[: quat[0].size], quat.reshape(len(quat), -1).std(0), atol=1e-6)


@pytest.mark.slow
def test_denormalize_undoes_normalize_within_float32(aist_store) -> None:
    kw = {"split": "train", "motion": MOTION, "audio": AUDIO, "window_frames": 32, "fit": "crop"}
    plain, normed = (
        MeasureDataset(aist_store, **kw),
        MeasureDataset(aist_store, normalize=True, **kw),
    )
    assert normed.source.normalized == {"motion": MOTION, "audio": [AUDIO]}
    for i in (0, len(plain) - 1):
        a, z = plain[i], normed[i]
        assert not torch.allclose(a["motion"], z["motion"])
        for key in ("motion", "audio"):
            scale = float(a[key].abs().max()) + 1.0
            back = normed.denormalize(z[key], key)
            np.testing.assert_allclose(back.numpy(), a[key].numpy(), atol=4e-7 * scale)
            back = normed.denormalize(z[key].numpy(), key)
            np.testing.assert_allclose(back, a[key].numpy(), atol=4e-7 * scale)
        assert not z["motion"][~z["mask"]].any()  # the crop's padding stays zero
    only = MeasureDataset(aist_store, normalize=["motion/trans"], **kw)
    np.testing.assert_array_equal(
        only[0]["motion"][:, :96].numpy(), plain[0]["motion"][:, :96].numpy()
    )
    with pytest.raises(InputError, match="not a part of this dataset"):
        MeasureDataset(aist_store, normalize=["motion/euler"], **kw)
    with pytest.raises(StoreError, match=r"normalization table has no 'motion/euler'.*"):
        MeasureDataset(aist_store, split="train", motion="motion/euler", audio=None, normalize=True)


# ---------------------------------------------------------------------------- augmentation

ALL = ["motion/rotmat", "motion/quat", "motion/rot6d", "motion/axis_angle", "motion/euler"]
ALL += ["motion/trans", "motion/positions"]


@pytest.mark.slow
def test_mirror_twice_is_the_identity_bit_for_bit_and_agrees_across_representations(
    aist_store,
) -> None:
    ds = MeasureDataset(aist_store, split="train", motion=ALL, audio=AUDIO, augment=Mirror(p=1.0))
    rig, plan = store_rig(ds.store), ds.columns["motion"]
    x = ds.source.raw(0)["motion"]
    once = mirror_rows(x, plan, rig)
    np.testing.assert_array_equal(mirror_rows(once, plan, rig), x)
    assert not np.array_equal(once, x)
    np.testing.assert_array_equal(ds.source.item(0)["motion"], once)  # p=1: every item
    part = {p.name: p for p in plan}

    def rot(rows, name):
        p = part[name]
        v = rows[:, p.start : p.stop].reshape(-1, *p.shape).astype(np.float64)
        if name == "motion/rotmat":
            return Rotation.from_matrix(v.reshape(-1, 3, 3))
        if name == "motion/quat":
            return Rotation.from_quat(v.reshape(-1, 4)[:, [1, 2, 3, 0]])
        return Rotation.from_rotvec(v.reshape(-1, 3))

    # independent closed form: mirrored local rotations are M R M of the twin joint
    m = np.diag([-1.0, 1.0, 1.0])
    joints = part["motion/rotmat"].shape[0]
    r = rot(x, "motion/rotmat").as_matrix().reshape(len(x), joints, 3, 3)
    want = (m @ r @ m)[:, rig.pairs]
    for name in ("motion/rotmat", "motion/quat", "motion/axis_angle"):
        got = rot(once, name).as_matrix().reshape(want.shape)
        np.testing.assert_allclose(got, want, atol=2e-6)
    p = part["motion/positions"]
    pos = x[:, p.start : p.stop].reshape(len(x), -1, 3)
    np.testing.assert_array_equal(
        once[:, p.start : p.stop].reshape(pos.shape), pos[:, rig.pairs] * [-1, 1, 1]
    )
    with pytest.raises(InputError, match="mirror augmentation has no exact rule for"):
        MeasureDataset(
            aist_store,
            split="train",
            motion="motion/keypoints2d",
            audio=None,
            augment="mirror",
        )


@pytest.mark.slow
def test_yaw_turns_the_root_and_world_vectors_and_keeps_speeds_and_heights(aist_store) -> None:
    ds = MeasureDataset(aist_store, split="train", motion=ALL, audio=None, augment=Yaw())
    rig, plan = store_rig(ds.store), ds.columns["motion"]
    part = {p.name: p for p in plan}
    x = ds.source.raw(2)["motion"]
    turned = yaw_rows(x, plan, rig, 0.7)
    y = Rotation.from_rotvec([0.0, 0.7, 0.0])
    p = part["motion/rotmat"]
    r0 = x[:, p.start : p.start + 9].reshape(-1, 3, 3).astype(np.float64)
    np.testing.assert_allclose(
        turned[:, p.start : p.start + 9].reshape(-1, 3, 3), y.as_matrix() @ r0, atol=2e-6
    )
    np.testing.assert_array_equal(turned[:, p.start + 9 : p.stop], x[:, p.start + 9 : p.stop])
    order = ds.store.zarr("motion/euler").attrs["order"]
    order = order[0] if isinstance(order, list) else order
    decode = {  # the root's stored values → matrices, each by its own decoder
        "motion/rot6d": lambda v: rot6d_to_rotmat(v),
        "motion/axis_angle": lambda v: Rotation.from_rotvec(v).as_matrix(),
        "motion/euler": lambda v: Rotation.from_euler(order, v).as_matrix(),
    }
    for name, to_matrix in decode.items():
        q = part[name]
        width = q.stop - q.start
        root = turned[:, q.start : q.start + width // q.shape[0]].astype(np.float64)
        np.testing.assert_allclose(to_matrix(root), y.as_matrix() @ r0, atol=1e-5)
        rest = slice(q.start + width // q.shape[0], q.stop)
        np.testing.assert_array_equal(turned[:, rest], x[:, rest])
    q = part["motion/quat"]
    got = Rotation.from_quat(turned[:, q.start : q.start + 4][:, [1, 2, 3, 0]].astype(np.float64))
    np.testing.assert_allclose(got.as_matrix(), y.as_matrix() @ r0, atol=2e-6)
    t = part["motion/trans"]
    tr, tt = x[:, t.start : t.stop], turned[:, t.start : t.stop]
    np.testing.assert_allclose(tt[:, 1], tr[:, 1], atol=1e-6)  # heights kept
    speed = lambda v: np.linalg.norm(np.diff(v, axis=0), axis=-1)  # noqa: E731
    np.testing.assert_allclose(speed(tt), speed(tr), atol=1e-5)  # kinetic: speeds kept
    q = part["motion/positions"]
    pos, pt = (v[:, q.start : q.stop].reshape(len(x), -1, 3) for v in (x, turned))
    np.testing.assert_allclose(speed(pt), speed(pos), atol=1e-5)
    np.testing.assert_allclose(pt[..., 1], pos[..., 1], atol=1e-6)


@pytest.mark.slow
def test_augmentation_is_deterministic_per_seed_epoch_and_index_whatever_the_workers(
    aist_store,
) -> None:
    kw = {"split": "train", "motion": MOTION, "audio": None, "augment": ("mirror", "yaw")}
    a, b = MeasureDataset(aist_store, seed=3, **kw), MeasureDataset(aist_store, seed=3, **kw)
    other = MeasureDataset(aist_store, seed=4, **kw)
    for i in range(len(a)):
        assert torch.equal(a[i]["motion"], b[i]["motion"])
    assert any(not torch.equal(a[i]["motion"], other[i]["motion"]) for i in range(len(a)))
    first = [a.source.item(i, epoch=0)["motion"] for i in range(len(a))]
    a.set_epoch(1)
    assert any(not np.array_equal(first[i], a.source.item(i)["motion"]) for i in range(len(a)))
    a.set_epoch(0)
    index = {
        (s, int(f)): i
        for i, (s, f) in enumerate(
            zip(a.source.spans.seq_ids, a.source.spans.frame_start, strict=True)
        )
    }
    ref = training_loader(a, 2, seed=1)
    two = training_loader(b, 2, seed=1, num_workers=2)  # persistent workers
    for epoch in range(2):
        left, right = list(ref), list(two)
        assert len(left) == len(right) > 1
        for x, y in zip(left, right, strict=True):
            assert x["seq_id"] == y["seq_id"] and torch.equal(x["motion"], y["motion"])
            for k, seq_id in enumerate(y["seq_id"]):  # each item is its epoch's draw
                i = index[(seq_id, int(y["frame_start"][k]))]
                want = a.source.item(i, epoch=epoch)["motion"]
                np.testing.assert_array_equal(y["motion"][k, : len(want)].numpy(), want)


@pytest.mark.slow
@pytest.mark.real_data
def test_mirrored_bvh_rotations_pose_the_mirrored_skeleton(bvh_store) -> None:
    """On the real CMU rig: forward kinematics of the mirrored local rotations and translation
    is the mirror image of the original pose (exact with the rest offsets made symmetric; the
    rig's own offsets differ from their mirror by 1.5 cm at most)."""
    from dancedata.compute.fk import forward_kinematics

    spec = ["motion/rotmat", "motion/trans"]
    ds = MeasureDataset(bvh_store, motion=spec, audio=None, augment=Mirror(p=1.0))
    rig = store_rig(ds.store)
    skeleton = ds.store.group_attrs("motion")["skeleton"]
    offsets = np.asarray(skeleton["offsets"], dtype=np.float64)
    symmetric = (offsets + offsets[rig.pairs] * [-1, 1, 1]) / 2
    x, joints = ds.source.raw(3)["motion"].astype(np.float64), len(rig.pairs)
    m = ds.source.item(3)["motion"].astype(np.float64)

    def pose(rows):
        rot = rows[:, : 9 * joints].reshape(-1, joints, 3, 3)
        return forward_kinematics(skeleton["parents"], symmetric, rot, rows[:, 9 * joints :])

    want = pose(x)[:, rig.pairs] * [-1, 1, 1]
    np.testing.assert_allclose(pose(m), want, atol=1e-5)
    assert np.abs(pose(m) - pose(x)).max() > 0.5  # the pose really changed sides
