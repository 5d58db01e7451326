"""The plain PyTorch idiom over window datasets (issue 23 item 4) and datasets over an S3 store
in data-loader workers (issue 22: the store's URL survives pickling).

``DataLoader(MeasureDataset(...), batch_size=8, num_workers=2)`` with torch's default collate
used to die in the workers with "Trying to resize storage that is not resizable" (measures of
different lengths cannot be stacked). The dataset's ``__getitems__`` now pads each batch to its
longest window with a mask; every batch is checked against an independent read
(``DanceStore.iter_measures``) and against ``pad_collate`` of the unpadded items.

Stores are built by the real pipeline from synthetic AIST++ files; the S3 store lives on a moto
S3 server on loopback (tests/s3_server.py).
"""

from __future__ import annotations

import pickle
from pathlib import Path

import numpy as np
import pytest

torch = pytest.importorskip("torch")
from torch.utils.data import DataLoader  # noqa: E402

from dancedata.read.torch_batching import PadCollate, pad_collate  # noqa: E402
from dancedata.read.torch_data import MeasureDataset, SecondsDataset  # noqa: E402
from tests.s3_server import moto_s3  # noqa: E402

# slow: DataLoader workers over a featurized store, local and S3
pytestmark = pytest.mark.slow


@pytest.fixture(scope="module")
def raw(tmp_path_factory) -> Path:
    from dancedata.synth.aist import synth_aist

    root = tmp_path_factory.mktemp("idiom-raw")
    synth_aist(root, n_sequences=4, seed=0)
    return root


@pytest.fixture(scope="module")
def store(raw, tmp_path_factory) -> Path:
    from dancedata.featurize.featurize import FeaturizeOptions, featurize
    from dancedata.featurize.segment import SegmentOptions, segment
    from dancedata.ingest.aist import AistIngestOptions, ingest_aist

    path = tmp_path_factory.mktemp("idiom") / "store"
    ingest_aist(path, raw, AistIngestOptions())
    featurize(path, FeaturizeOptions())
    segment(path, SegmentOptions())
    return path


def test_default_collate_with_two_workers_stacks_measures_of_different_lengths(store) -> None:
    import dancedata

    ds = MeasureDataset(store, split="train")
    assert len(set(ds.lengths.tolist())) > 1  # 110, 111 and 160 frames
    reference = list(dancedata.open_store(store).iter_measures(split="train"))
    batches = list(DataLoader(ds, batch_size=8, num_workers=2))
    assert len(batches) == -(-len(ds) // 8) and len(ds) == len(reference)
    mixed = 0
    seen = 0
    for batch in batches:
        total = batch["motion"].shape[1]
        assert batch["audio"].shape[1] == total == int(batch["length"].max())
        assert batch["motion"].shape[2] == 225 and batch["audio"].shape[2] == 35
        mixed += len(set(batch["length"].tolist())) > 1
        for b in range(batch["motion"].shape[0]):
            ref = reference[seen]
            n = ref.motion.shape[0]
            assert batch["seq_id"][b] == ref.seq_id and int(batch["measure"][b]) == ref.measure
            assert int(batch["length"][b]) == n
            assert batch["mask"][b].tolist() == [t < n for t in range(total)]
            np.testing.assert_array_equal(batch["motion"][b, :n].numpy(), ref.motion)
            np.testing.assert_array_equal(batch["audio"][b, :n].numpy(), ref.audio)
            assert not batch["motion"][b, n:].any() and not batch["audio"][b, n:].any()
            seen += 1
    assert mixed >= 1 and seen == len(reference)  # at least one batch mixes lengths


def test_pad_collate_of_padded_batch_items_equals_pad_collate_of_single_items(store) -> None:
    ds = MeasureDataset(store, split="train")
    indices = [0, len(ds) - 1, 3, len(ds) - 2]
    assert len({int(ds.lengths[i]) for i in indices}) > 1
    for collate in (pad_collate, PadCollate(multiple_of=16), PadCollate(pad_value=-1.0)):
        padded = collate(ds.__getitems__(indices))
        single = collate([ds[i] for i in indices])
        assert padded.keys() == single.keys()
        for key, value in single.items():
            if isinstance(value, torch.Tensor):
                assert torch.equal(padded[key], value), key
            else:
                assert padded[key] == value, key
    short = int(np.argmin(ds.lengths[indices]))
    batch = PadCollate(pad_value=-1.0)(ds.__getitems__(indices))
    n = int(batch["lengths"][short])
    assert (batch["motion"][short, n:] == -1.0).all() and n < batch["motion"].shape[1]


def test_fixed_length_items_are_left_as_they_are(store) -> None:
    ds = SecondsDataset(store, split="train", seconds=1.0, window_frames=32, fit="crop")
    items = ds.__getitems__([0, 1])
    for i, item in enumerate(items):
        single = ds[i]
        assert item["motion"].shape == (32, 225)
        assert torch.equal(item["motion"], single["motion"])
        assert torch.equal(item["mask"], single["mask"])


# -- a dataset over an S3 store in spawned workers ----------------------------------------------
BUCKET = "dance"


@pytest.fixture(scope="module")
def s3_store(raw) -> str:
    from dancedata.featurize.featurize import FeaturizeOptions, featurize
    from dancedata.ingest.aist import AistIngestOptions, ingest_aist

    url = f"s3://{BUCKET}/s"
    with moto_s3(BUCKET):
        ingest_aist(url, raw, AistIngestOptions())
        featurize(url, FeaturizeOptions(audio=False, representations=["rotmat"]))
        yield url


def test_s3_dataset_survives_pickling_and_spawned_workers(s3_store) -> None:
    ds = SecondsDataset(s3_store, split="train", seconds=1.0, audio=None)
    assert ds.store.locator == s3_store
    copy = pickle.loads(pickle.dumps(ds))
    assert copy.source._store is None and copy.source.locator == s3_store
    np.testing.assert_array_equal(copy[0]["motion"].numpy(), ds[0]["motion"].numpy())
    assert copy.store.locator == s3_store and copy.store.version == ds.store.version
    serial = list(DataLoader(ds, batch_size=4))
    spawned = list(DataLoader(ds, batch_size=4, num_workers=2, multiprocessing_context="spawn"))
    assert len(serial) == len(spawned) > 1
    for x, y in zip(serial, spawned, strict=True):
        assert x["seq_id"] == y["seq_id"]
        assert torch.equal(x["motion"], y["motion"]) and torch.equal(x["mask"], y["mask"])


def test_local_locator_is_the_path_string(store) -> None:
    ds = MeasureDataset(store, split="train", audio=None)
    assert ds.store.locator == str(store)
    assert pickle.loads(pickle.dumps(ds)).store.path == Path(store)


def test_batch_parcel_pickles_as_one_shared_buffer_and_unpacks_to_the_batch(store) -> None:
    from multiprocessing.reduction import ForkingPickler

    for options in ({}, {"window_frames": 96, "fit": "resample"}):
        ds = MeasureDataset(store, split="train", **options)
        indices = [len(ds) - 1, 0, 3]
        expected = ds.batch(indices, multiple_of=16)
        parcel = ds.batch_parcel(indices, multiple_of=16)
        assert parcel.flat.is_shared() and set(parcel.shapes) == {"motion", "audio"}
        blob = bytes(ForkingPickler.dumps(parcel))
        for unpacked in (parcel.unpack(), pickle.loads(blob)):
            assert isinstance(unpacked, dict) and unpacked.keys() == expected.keys()
            for key, value in expected.items():
                if isinstance(value, torch.Tensor):
                    assert unpacked[key].dtype == value.dtype, key
                    assert torch.equal(unpacked[key], value), key
                    assert unpacked[key].is_contiguous()
                else:
                    assert unpacked[key] == value, key
        assert len(blob) < 20_000  # the windows themselves are not in the pickle
