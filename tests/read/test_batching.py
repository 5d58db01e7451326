"""Batching for training (issue 14 item 1): padding collate, fixed-length windows, length
buckets, N-measure and sliding-second windows, seeded orders, data-loader workers.

The store is built by the real pipeline (synth aist → ingest → featurize → segment) from 4
synthetic sequences (3 in the crossmodal train split; measures of 110, 111 and 160 frames).
Every window is checked against an independent read (``iter_measures`` or ``DanceStore.view``
sliced by hand), resampling against closed forms, ``np.interp`` and scipy's ``Slerp``, spans
against brute-force enumeration.
"""

from __future__ import annotations

import math
import pickle
from pathlib import Path

import numpy as np
import pytest
from scipy.spatial.transform import Rotation, Slerp

from dancedata.errors import InputError
from dancedata.read.batching import bucket_batches, epoch_permutation, lengths_mask
from dancedata.read.window_fit import (
    ColumnPart,
    fit_window,
    orthonormal_rotmat_to_quat,
    resample_window,
)
from dancedata.read.window_spans import measure_groups, sliding_starts

torch = pytest.importorskip("torch")
from torch.utils.data import DataLoader  # noqa: E402

from dancedata.read.torch_batching import (  # noqa: E402
    LengthBucketSampler,
    PadCollate,
    SeededShuffleSampler,
    pad_collate,
    training_loader,
)
from dancedata.read.torch_data import MeasureDataset, SecondsDataset  # noqa: E402


@pytest.fixture(scope="module")
def store(tmp_path_factory) -> Path:
    from dancedata.featurize.featurize import FeaturizeOptions, featurize
    from dancedata.featurize.segment import SegmentOptions, segment
    from dancedata.ingest.aist import AistIngestOptions, ingest_aist
    from dancedata.synth.aist import synth_aist

    root = tmp_path_factory.mktemp("batching")
    synth_aist(root / "raw", n_sequences=4, seed=0)
    path = root / "store"
    ingest_aist(path, root / "raw", AistIngestOptions())
    featurize(path, FeaturizeOptions())
    segment(path, SegmentOptions())
    return path


@pytest.fixture(scope="module")
def opened(store):
    import dancedata

    return dancedata.open_store(store)


# ------------------------------------------------------------------------- padding collate


@pytest.mark.slow
def test_plain_default_collate_pads_measures_of_different_lengths(store) -> None:
    # It raised RuntimeError; the dataset's __getitems__ now pads each batch (test_torch_idiom).
    ds = MeasureDataset(store, split="train")
    assert len(set(ds.lengths.tolist())) > 1
    batches = list(DataLoader(ds, batch_size=8))
    assert sum(len(b["seq_id"]) for b in batches) == len(ds)
    for batch in batches:
        assert batch["mask"].sum(1).tolist() == batch["length"].tolist()


@pytest.mark.slow
def test_pad_collate_batch_8_matches_per_item_reads(store, opened) -> None:
    ds = MeasureDataset(store, split="train")
    reference = list(opened.iter_measures(split="train"))
    assert len(ds) == len(reference) > 8
    seen = 0
    for batch in DataLoader(ds, batch_size=8, collate_fn=pad_collate):
        total = batch["motion"].shape[1]
        assert batch["audio"].shape[1] == total == int(batch["lengths"].max())
        for b in range(batch["motion"].shape[0]):
            ref = reference[seen]
            n = ref.motion.shape[0]
            assert batch["seq_id"][b] == ref.seq_id and int(batch["measure"][b]) == ref.measure
            assert int(batch["lengths"][b]) == n == ref.frame_stop - ref.frame_start
            assert batch["mask"][b].tolist() == [t < n for t in range(total)]
            np.testing.assert_array_equal(batch["motion"][b, :n].numpy(), ref.motion)
            np.testing.assert_array_equal(batch["audio"][b, :n].numpy(), ref.audio)
            assert not batch["motion"][b, n:].any() and not batch["audio"][b, n:].any()
            np.testing.assert_array_equal(batch["genre"][b].numpy(), ref.genre_onehot)
            seen += 1
    assert seen == len(reference)


@pytest.mark.slow
def test_pad_collate_rounds_up_and_old_windows_api_still_works(store) -> None:
    ds = MeasureDataset(store, split="train", audio=None)
    batch = PadCollate(multiple_of=16)([ds[i] for i in range(len(ds) - 3, len(ds))])
    assert batch["motion"].shape[1] % 16 == 0 and "audio" not in batch
    assert batch["mask"].sum(1).tolist() == batch["lengths"].tolist()
    assert batch["length"].tolist() == batch["lengths"].tolist()  # as torch_data's batches
    window = ds.windows[len(ds) - 1]
    assert window.frame_stop - window.frame_start == ds.lengths[-1] == window.motion.shape[0]
    assert window.audio is None


# ----------------------------------------------------------------------- fixed-length windows


def test_resample_closed_form_on_a_linear_ramp() -> None:
    length, frames = 131, 128
    t = np.arange(length, dtype=np.float64)
    x = np.stack([2.0 + 0.5 * t, -1.0 + 0.25 * t, 3.0 - 0.125 * t], axis=1).astype(np.float32)
    plan = [ColumnPart("motion/trans", 0, 3, "linear")]
    out = resample_window(x, plan, frames)
    s = np.arange(frames) * (length - 1) / (frames - 1)
    expected = np.stack([2.0 + 0.5 * s, -1.0 + 0.25 * s, 3.0 - 0.125 * s], axis=1)
    np.testing.assert_allclose(out, expected, atol=1e-4)
    assert out[0, 0] == x[0, 0] and out[-1, 0] == x[-1, 0]  # corners kept exactly


def test_resample_moves_events_without_smearing_them() -> None:
    x = np.zeros((160, 1), np.float32)
    x[[0, 40, 80, 120, 159], 0] = 1
    out = resample_window(x, [ColumnPart("audio/beats", 0, 1, "event")], 128)
    assert set(np.unique(out)) == {0.0, 1.0} and out.sum() == 5
    assert np.flatnonzero(out[:, 0]).tolist() == [
        round(i * 127 / 159) for i in (0, 40, 80, 120)
    ] + [127]


def test_slerp_midpoints_against_scipy() -> None:
    rng = np.random.default_rng(3)
    length, joints = 5, 24
    rot = Rotation.random(length * joints, random_state=rng)
    mats = rot.as_matrix().reshape(length, joints, 3, 3)
    x = mats.reshape(length, joints * 9).astype(np.float32)
    plan = [ColumnPart("motion/rotmat", 0, joints * 9, "slerp")]
    out = resample_window(x, plan, 2 * length - 1).reshape(-1, joints, 3, 3)
    for j in range(joints):
        frames = Rotation.from_matrix(mats[:, j].astype(np.float32).astype(np.float64))
        mids = Slerp(np.arange(length), frames)(np.arange(length - 1) + 0.5)
        # scipy takes the shorter arc as we do (quaternion sign chosen per pair)
        np.testing.assert_allclose(out[1::2, j], mids.as_matrix(), atol=2e-6)
        np.testing.assert_allclose(out[0::2, j], mats[:, j], atol=2e-6)


def test_rotmat_to_quat_matches_scipy_including_half_turns() -> None:
    rot = Rotation.random(20_000, random_state=np.random.default_rng(9))
    half_turns = Rotation.from_rotvec(np.pi * np.vstack([np.eye(3), [[0.6, 0.8, 0.0]]]))
    for r in (rot, half_turns):
        q = orthonormal_rotmat_to_quat(r.as_matrix())
        ref = r.as_quat()[:, [3, 0, 1, 2]]  # scipy is xyzw
        sign = np.sign(np.sum(q * ref, axis=1, keepdims=True))
        np.testing.assert_allclose(q, sign * ref, atol=1e-12)


@pytest.mark.slow
def test_resampled_dataset_windows_match_np_interp_and_scipy_slerp(store) -> None:
    frames = 64
    ds = MeasureDataset(store, split="train", window_frames=frames, fit="resample")
    methods = {p.name: p.method for p in ds.resampling["motion"] + ds.resampling["audio"]}
    assert methods["motion/rotmat"] == "slerp" and methods["motion/trans"] == "linear"
    assert methods["audio/beats"] == "event" and methods["audio/mfcc"] == "linear"
    for i in (0, len(ds) - 1):
        raw = ds.windows[i]
        item = ds[i]
        n = raw.motion.shape[0]
        assert item["motion"].shape == (frames, 225) and item["audio"].shape == (frames, 35)
        assert item["length"] == frames and bool(item["mask"].all())
        pos = np.linspace(0, n - 1, frames)
        for c in range(6, 9):  # translation
            np.testing.assert_allclose(
                item["motion"][:, c].numpy(), np.interp(pos, np.arange(n), raw.motion[:, c]),
                atol=1e-5,
            )  # fmt: skip
        for c in range(1, 21):  # MFCC
            np.testing.assert_allclose(
                item["audio"][:, c].numpy(), np.interp(pos, np.arange(n), raw.audio[:, c]),
                rtol=1e-5, atol=1e-3,
            )  # fmt: skip
        mats = raw.motion[:, 9:].reshape(n, 24, 3, 3).astype(np.float64)
        for j in (0, 5, 23):
            expected = Slerp(np.arange(n), Rotation.from_matrix(mats[:, j]))(pos).as_matrix()
            got = item["motion"][:, 9:].numpy().reshape(frames, 24, 3, 3)[:, j]
            np.testing.assert_allclose(got, expected, atol=1e-5)
        assert item["audio"][:, 34].sum() == raw.audio[:, 34].sum()  # beats kept


@pytest.mark.slow
def test_crop_and_pad(store) -> None:
    lengths = MeasureDataset(store, split="train").lengths
    short, longest = int(lengths.min()), int(lengths.max())
    width = (short + longest) // 2
    crop = MeasureDataset(store, split="train", window_frames=width, fit="crop")
    for i in range(len(crop)):
        raw, item = crop.windows[i], crop[i]
        kept = min(raw.motion.shape[0], width)
        assert item["length"] == kept and int(item["mask"].sum()) == kept
        np.testing.assert_array_equal(item["motion"][:kept].numpy(), raw.motion[:kept])
        assert not item["motion"][kept:].any()
    pad = MeasureDataset(store, split="train", window_frames=longest + 4, fit="pad")
    batch = next(iter(DataLoader(pad, batch_size=len(pad), collate_fn=pad_collate)))
    assert batch["motion"].shape[1] == longest + 4
    assert batch["lengths"].tolist() == lengths.tolist()
    assert batch["mask"].sum(1).tolist() == lengths.tolist()
    with pytest.raises(InputError, match="fit='pad' never drops frames"):
        MeasureDataset(store, split="train", window_frames=longest - 1, fit="pad")
    with pytest.raises(InputError, match="fit must be one of"):
        MeasureDataset(store, split="train", window_frames=64, fit="stretch")
    with pytest.raises(InputError, match="fit='pad'"):
        fit_window(np.zeros((10, 3), np.float32), [], 5, "pad")


# ------------------------------------------------------------------------------- buckets


def test_bucket_batches_cover_every_index_once_with_bounded_spread() -> None:
    rng = np.random.default_rng(0)
    lengths = rng.integers(100, 181, size=501)
    for max_spread in (0, 3, 10, None):
        for epoch in range(3):
            batches = bucket_batches(lengths, 8, seed=5, epoch=epoch, max_spread=max_spread)
            flat = np.concatenate(batches)
            assert sorted(flat.tolist()) == list(range(len(lengths)))
            assert all(1 <= len(b) <= 8 for b in batches)
            if max_spread is not None:
                assert max(int(np.ptp(lengths[b])) for b in batches) <= max_spread
        if max_spread is None:  # sorted runs: no batch is wider than the next 8 sorted lengths
            s = np.sort(lengths)
            worst = max(int(s[i + 7] - s[i]) for i in range(len(s) - 7))
            assert max(int(np.ptp(lengths[b])) for b in batches) <= worst
    full = bucket_batches(lengths, 8, seed=5, drop_last=True)
    assert all(len(b) == 8 for b in full) and len(full) == len(lengths) // 8


@pytest.mark.slow
def test_length_bucket_sampler_over_the_dataset(store) -> None:
    ds = MeasureDataset(store, split="train")
    sampler = LengthBucketSampler(ds.lengths, 8, seed=1, max_spread=2)
    for _ in range(2):  # two epochs
        seen = []
        for batch in DataLoader(ds, batch_sampler=sampler, collate_fn=pad_collate):
            assert int(batch["lengths"].max() - batch["lengths"].min()) <= 2
            assert batch["motion"].shape[1] == int(batch["lengths"].max())
            seen += list(zip(batch["seq_id"], batch["measure"].tolist(), strict=True))
        assert sorted(seen) == sorted((w.seq_id, w.measure) for w in ds.windows) and len(
            set(seen)
        ) == len(ds)


# ----------------------------------------------------------------- N-measure, sliding seconds


@pytest.mark.slow
@pytest.mark.parametrize(("n", "hop"), [(1, None), (2, None), (2, 1), (3, 2), (4, 1)])
def test_n_measure_windows_cover_brute_force_ranges(store, opened, n, hop) -> None:
    ds = MeasureDataset(store, split="train", n_measures=n, hop_measures=hop)
    rows = opened.measure_rows("train")
    expected = []
    for seq in dict.fromkeys(r["seq_id"] for r in rows):
        covered = opened.audio_frames(seq)
        mine = sorted(
            (r for r in rows if r["seq_id"] == seq and r["frame_stop"] <= covered),
            key=lambda r: r["measure"],
        )
        for k in range(0, len(mine) - n + 1, n if hop is None else hop):
            expected.append(
                (seq, mine[k]["measure"], mine[k]["frame_start"], mine[k + n - 1]["frame_stop"])
            )
    got = [(w.seq_id, w.measure, w.frame_start, w.frame_stop) for w in ds.windows]
    assert got == expected and len(got) > 0
    i = len(ds) // 2
    seq, _, a, b = expected[i]
    np.testing.assert_array_equal(ds[i]["motion"].numpy(), opened.view(seq, "fact_motion_225")[a:b])
    np.testing.assert_array_equal(ds[i]["audio"].numpy(), opened.view(seq, "fact_audio_35")[a:b])


@pytest.mark.slow
def test_windows_longer_than_every_sequence_are_an_error_not_an_empty_dataset(store) -> None:
    with pytest.raises(InputError, match="no 3600.0 s windows in split 'train'"):
        SecondsDataset(store, split="train", seconds=3600.0)
    with pytest.raises(InputError, match="no 500-measure windows"):
        MeasureDataset(store, split="train", n_measures=500)


def test_measure_groups_skip_gaps() -> None:
    seqs = ["a"] * 5 + ["b"] * 2
    measures = [0, 1, 2, 4, 5, 0, 1]
    starts = [0, 10, 20, 40, 50, 0, 12]
    stops = [10, 20, 30, 50, 60, 12, 24]
    assert measure_groups(seqs, measures, starts, stops, 2, 1) == [
        (0, 1), (1, 2), (3, 4), (5, 6)
    ]  # fmt: skip
    with pytest.raises(InputError):
        measure_groups(seqs, measures, starts, stops, 0)


@pytest.mark.slow
@pytest.mark.parametrize(("seconds", "hop"), [(1.0, None), (4.0, 1.0), (8.0, 2.5), (1.0, 0.35)])
def test_sliding_second_windows_cover_brute_force_ranges(store, opened, seconds, hop) -> None:
    ds = SecondsDataset(store, split="train", seconds=seconds, hop_seconds=hop)
    hop_s = seconds if hop is None else hop
    expected = []
    for seq in opened.seq_ids("train"):
        fps = float(opened.sequence(seq)["fps"])
        width = math.floor(seconds * fps + 0.5)
        available = min(int(opened.sequence(seq)["n_frames"]), opened.audio_frames(seq))
        starts = {math.floor(k * hop_s * fps + 0.5) for k in range(10_000)}
        expected += [
            (seq, s, s + width) for s in range(available) if s in starts and s + width <= available
        ]
    got = [(w.seq_id, w.frame_start, w.frame_stop) for w in ds.windows]
    assert got == expected and len(got) > 0
    seq, a, b = expected[-1]
    item = ds[len(ds) - 1]
    assert item["measure"] == -1 and item["length"] == b - a
    np.testing.assert_array_equal(item["motion"].numpy(), opened.view(seq, "fact_motion_225")[a:b])
    assert sliding_starts(59, 60, 30.0).size == 0


@pytest.mark.slow
def test_sliding_windows_resampled_to_fixed_frames(store) -> None:
    ds = SecondsDataset(store, split="train", seconds=1.0, window_frames=30)
    batch = next(iter(DataLoader(ds, batch_size=8)))  # plain default collate: all equal size
    assert batch["motion"].shape == (8, 30, 225) and bool(batch["mask"].all())


# --------------------------------------------------------------------- seeds and workers


@pytest.mark.slow
def test_same_seed_same_order_different_seed_different_order(store) -> None:
    ds = MeasureDataset(store, split="train")
    a = list(SeededShuffleSampler(len(ds), seed=7))
    assert a == list(SeededShuffleSampler(len(ds), seed=7))
    assert sorted(a) == list(range(len(ds)))
    assert a != list(SeededShuffleSampler(len(ds), seed=8))
    sampler = SeededShuffleSampler(len(ds), seed=7)
    assert list(sampler) != list(sampler)  # the epoch advances
    assert epoch_permutation(1000, 3, 2).tolist() == epoch_permutation(1000, 3, 2).tolist()

    def order(seed: int, bucket: bool) -> list[tuple[str, int]]:
        loader = training_loader(ds, 8, seed=seed, bucket=bucket)
        return [(s, int(m)) for b in loader for s, m in zip(b["seq_id"], b["measure"], strict=True)]

    for bucket in (False, True):
        assert order(11, bucket) == order(11, bucket)
        assert order(11, bucket) != order(12, bucket)
    lengths = np.arange(200) % 37
    one = [b.tolist() for b in bucket_batches(lengths, 8, seed=4)]
    assert one == [b.tolist() for b in bucket_batches(lengths, 8, seed=4)]
    assert one != [b.tolist() for b in bucket_batches(lengths, 8, seed=5)]


def _batches(loader) -> list[dict]:
    return [dict(b) for b in loader]


def _assert_same_batches(left: list[dict], right: list[dict]) -> None:
    assert len(left) == len(right) > 0
    for x, y in zip(left, right, strict=True):
        assert x.keys() == y.keys()
        for key in x:
            if isinstance(x[key], torch.Tensor):
                assert torch.equal(x[key], y[key]), key
            else:
                assert x[key] == y[key], key


@pytest.mark.slow
def test_two_workers_give_the_same_batches_as_none(store) -> None:
    ds = MeasureDataset(store, split="train")
    for bucket in (True, False):
        serial_loader = training_loader(ds, 8, seed=3, bucket=bucket, num_workers=0)
        forked_loader = training_loader(ds, 8, seed=3, bucket=bucket, num_workers=2)
        if not bucket:
            ds.preload()  # forked workers then share the parent's arrays
        epochs = []
        for _ in range(2):  # persistent workers; the sampler's epoch advances per pass
            serial, forked = _batches(serial_loader), _batches(forked_loader)
            _assert_same_batches(serial, forked)
            epochs.append([s for b in serial for s in b["seq_id"]])
        assert sorted(epochs[0]) == sorted(epochs[1]) and epochs[0] != epochs[1]


@pytest.mark.slow
def test_dataset_pickles_small_and_works_in_spawned_workers(store) -> None:
    ds = SecondsDataset(store, split="train", seconds=1.0, window_frames=32)
    ds[0]  # loads the arrays in this process: they must not travel in the pickle
    blob = pickle.dumps(ds)
    assert len(blob) < 50_000
    copy = pickle.loads(blob)
    assert copy.source._store is None
    _assert_same_batches([pad_collate([ds[0], ds[1]])], [pad_collate([copy[0], copy[1]])])
    loader = DataLoader(
        ds, batch_size=8, sampler=SeededShuffleSampler(len(ds), 2), collate_fn=pad_collate,
        num_workers=2, multiprocessing_context="spawn",
    )  # fmt: skip
    serial = DataLoader(
        ds, batch_size=8, sampler=SeededShuffleSampler(len(ds), 2), collate_fn=pad_collate
    )
    _assert_same_batches(_batches(serial), _batches(loader))


def test_lengths_mask() -> None:
    assert lengths_mask([2, 0, 3], 4).tolist() == [
        [True, True, False, False], [False] * 4, [True, True, True, False]
    ]  # fmt: skip


@pytest.mark.slow
@pytest.mark.parametrize(
    "options",
    [{}, {"window_frames": 128, "fit": "crop"}, {"window_frames": 96, "fit": "resample"}],
    ids=["measures", "crop", "resample"],
)
def test_batch_reads_equal_pad_collate_of_items(store, options) -> None:
    ds = MeasureDataset(store, split="train", **options)
    for bucket in (True, False):
        fast = _batches(training_loader(ds, 8, seed=6, bucket=bucket))
        per_item = _batches(training_loader(ds, 8, seed=6, bucket=bucket, collate_fn=pad_collate))
        _assert_same_batches(fast, per_item)
    indices = [len(ds) - 1, 0, 3]
    _assert_same_batches(
        [ds.batch(indices, multiple_of=16)], [PadCollate(16)([ds[i] for i in indices])]
    )
    sliding = SecondsDataset(store, split="train", seconds=1.0, hop_seconds=0.75, audio=None)
    _assert_same_batches(
        _batches(training_loader(sliding, 8, seed=1)),
        _batches(training_loader(sliding, 8, seed=1, collate_fn=pad_collate)),
    )
