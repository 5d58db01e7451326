"""Normalisation statistics of a training split: Chan's pairwise moments against numpy on the
concatenated rows, the ``stats`` step on a real store against the split's frames read directly
with zarr, the round trip normalise → denormalise, and the refusals."""

from __future__ import annotations

import json

import numpy as np
import pytest
import zarr

import dancedata
from dancedata.compute.normalization import Moments, denormalize, normalize
from tests.helpers import run_cli

# slow: a featurized 6-sequence store
pytestmark = pytest.mark.slow


def test_pairwise_moments_equal_numpy_in_any_block_order():
    rng = np.random.default_rng(0)
    rows = rng.normal(3.0, 2.0, (1000, 5)) * [1, 10, 0.1, 1e3, 1]
    rows[:, 4] = 7.0  # a constant column
    cuts = np.sort(rng.choice(np.arange(1, 1000), 9, replace=False))
    blocks = np.split(rows, cuts)
    for order in (range(len(blocks)), reversed(range(len(blocks)))):
        total = Moments.empty(5)
        for i in order:
            total = total.add(Moments.of(blocks[i]))
        assert total.count == 1000
        np.testing.assert_allclose(total.mean, rows.mean(axis=0), rtol=1e-12)
        np.testing.assert_allclose(total.std, rows.std(axis=0), rtol=1e-10, atol=1e-12)
    weights = rng.integers(0, 3, 1000)
    weighted = Moments.of(rows, weights)
    repeated = np.repeat(rows, weights, axis=0)
    np.testing.assert_allclose(weighted.mean, repeated.mean(axis=0), rtol=1e-12)
    np.testing.assert_allclose(weighted.std, repeated.std(axis=0), rtol=1e-10, atol=1e-12)


def test_normalize_round_trip_and_constant_columns():
    rng = np.random.default_rng(1)
    x = rng.normal(0, 1, (50, 3, 4)).astype(np.float32)
    x[..., 0] = 2.5
    m = Moments.of(x)
    mean, std = m.mean.reshape(3, 4), m.std.reshape(3, 4)
    z = normalize(x, mean, std)
    assert np.all(z[..., 0] == 0.0)
    np.testing.assert_allclose(z[..., 1:].reshape(50, -1).std(axis=0), 1.0, rtol=1e-5)
    np.testing.assert_allclose(denormalize(z, mean, std), x, atol=1e-6)


@pytest.fixture(scope="module")
def store(tmp_path_factory):
    root = tmp_path_factory.mktemp("stats")
    raw, store = root / "raw", root / "store"
    run_cli("synth", "aist", str(raw), "--sequences", "6", "--seed", "2", "--quiet")
    run_cli("ingest", "aist", str(raw), "--store", str(store), "--quiet")
    run_cli("featurize", str(store), "--stems", "none", "--quiet")
    return store


def test_stats_equal_the_split_frames_read_directly(store):
    out = run_cli("stats", str(store), "--arrays", "motion/quat,audio/mfcc", "--json")
    version = json.loads(out.stdout)["version"]
    ds = dancedata.open_store(store)
    assert ds.version == version
    train = ds.seq_ids(split="train")
    assert train
    root = zarr.open_group(str(store / "versions" / version / "data.zarr"), mode="r")
    quat = np.concatenate(
        [
            root["motion/quat"][ds.sequence(s)["frame_start"] : ds.sequence(s)["frame_stop"]]
            for s in train
        ]
    ).astype(np.float64)
    got = ds.normalization("motion/quat")
    assert got.mean.shape == (24, 4) and got.n_frames == len(quat)
    np.testing.assert_allclose(got.mean, quat.mean(axis=0), rtol=1e-9, atol=1e-12)
    np.testing.assert_allclose(got.std, quat.std(axis=0), rtol=1e-9, atol=1e-12)
    mfcc = np.concatenate([ds.audio(s, "mfcc") for s in train]).astype(np.float64)
    got = ds.normalization("audio/mfcc")
    np.testing.assert_allclose(got.mean, mfcc.mean(axis=0), rtol=1e-9)
    np.testing.assert_allclose(got.std, mfcc.std(axis=0), rtol=1e-9)
    again = run_cli("stats", str(store), "--arrays", "motion/quat,audio/mfcc", "--json")
    assert json.loads(again.stdout)["created"] is False
    run_cli("validate", str(store))


def test_stats_refuse_unknown_arrays_and_splits(store):
    bad = run_cli("stats", str(store), "--arrays", "motion/nope", check=False)
    assert bad.returncode == 1 and "has no array 'motion/nope'" in bad.stderr
    assert "Traceback" not in bad.stderr
    bad = run_cli("stats", str(store), "--split", "nosuch", check=False)
    assert bad.returncode == 1 and "no split 'nosuch'" in bad.stderr
    ds = dancedata.open_store(store)
    with pytest.raises(dancedata.errors.StoreError, match="no 'motion/rotmat'"):
        ds.normalization("motion/rotmat")
