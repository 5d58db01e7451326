"""featurize --resampler (issue 14, item 6 bullet 2).

FACT-era tooling loaded music with librosa < 0.10, whose ``librosa.load`` default resampler was
``kaiser_best`` (resampy); librosa >= 0.10 defaults to ``soxr_hq``. The store's features must
equal librosa called directly with the chosen ``res_type``, and the choice must be recorded
(manifest config, fingerprint, feature-cache key).
"""

from __future__ import annotations

import json

import librosa
import numpy as np
import pyarrow.parquet as pq
import pytest
import soundfile as sf
import zarr

from dancedata.compute.audio_features import AudioFeatureConfig
from dancedata.featurize.audio_track import family_cache_key
from dancedata.featurize.families.audio_base import AudioSettings
from dancedata.io.audio_decode import decode_mono
from dancedata.synth.music import synth_dance_music
from tests.helpers import run_cli

SR = 30720  # 60 fps × hop 512


@pytest.fixture(scope="module")
def wav(tmp_path_factory):
    path = tmp_path_factory.mktemp("resampler") / "song.wav"
    sf.write(path, synth_dance_music(117.0, 8.0, sr=22050, seed=5), 22050)
    return path


@pytest.mark.slow
@pytest.mark.parametrize("res_type", ["soxr_hq", "kaiser_best", "kaiser_fast", "fft"])
def test_decode_equals_librosa_load_with_that_res_type(wav, res_type):
    pytest.importorskip("resampy")
    ours = decode_mono(wav, SR, res_type=res_type).y
    reference, _ = librosa.load(str(wav), sr=SR, res_type=res_type)
    np.testing.assert_array_equal(ours, reference)


@pytest.mark.slow
def test_resamplers_differ_by_about_a_percent(wav):
    """What the choice is worth: on this music MFCC and onset strength move by ~1 %."""
    pytest.importorskip("resampy")
    soxr = decode_mono(wav, SR, res_type="soxr_hq").y
    kaiser = decode_mono(wav, SR, res_type="kaiser_best").y
    for feature in (
        lambda y: librosa.onset.onset_strength(y=y, sr=SR, hop_length=512),
        lambda y: librosa.feature.mfcc(y=y, sr=SR, n_mfcc=20, hop_length=512),
    ):
        a, b = feature(soxr), feature(kaiser)
        relative = np.linalg.norm(a - b) / np.linalg.norm(b)
        assert 1e-4 < relative < 0.05


def test_cache_key_depends_on_the_resampler():
    settings = AudioSettings()
    keys = {
        family_cache_key("fact", settings, AudioFeatureConfig(res_type=r), "ab" * 32, 120.0)
        for r in ("soxr_hq", "kaiser_best")
    }
    assert len(keys) == 2


@pytest.mark.slow
def test_unknown_resampler_is_refused(wav):
    from dancedata.errors import InputError

    with pytest.raises(InputError, match="unknown resampler 'sinc_best'"):
        decode_mono(wav, SR, res_type="sinc_best")


@pytest.fixture(scope="module")
def ingested(tmp_path_factory):
    root = tmp_path_factory.mktemp("resampler-store")
    raw, store = root / "raw", root / "store"
    run_cli("synth", "aist", str(raw), "--sequences", "1", "-q")
    run_cli("ingest", "aist", str(raw), "--store", str(store), "-q")
    return store


def _featurize(store, *extra):
    out = run_cli(
        "featurize",
        str(store),
        "--no-motion",
        "--audio-families",
        "fact",
        "--version",
        "v1",
        "--json",
        *extra,
    )
    version = json.loads(out.stdout)["version"]
    manifest = json.loads((store / "versions" / version / "manifest.json").read_text())
    root = zarr.open_group(str(store / "versions" / version / "data.zarr"), mode="r")
    return manifest, root


@pytest.mark.slow
def test_featurize_records_the_resampler_and_matches_librosa(ingested):
    pytest.importorskip("resampy")
    default_manifest, default_root = _featurize(ingested)
    kaiser_manifest, kaiser_root = _featurize(ingested, "--resampler", "kaiser_best")
    assert default_manifest["config"]["audio"]["res_type"] == "soxr_hq"
    assert kaiser_manifest["config"]["audio"]["res_type"] == "kaiser_best"
    assert default_manifest["fingerprint"] != kaiser_manifest["fingerprint"]
    path = pq.read_table(ingested / "versions/v1/music.parquet").to_pylist()[0]["path"]
    for res_type, root in (("soxr_hq", default_root), ("kaiser_best", kaiser_root)):
        y, sr = librosa.load(path, sr=SR, res_type=res_type)
        env = librosa.onset.onset_strength(y=y, sr=sr, hop_length=512)
        mfcc = librosa.feature.mfcc(y=y, sr=sr, n_mfcc=20, hop_length=512).T
        stored_env = np.asarray(root["audio/onset_env"][:])
        n = stored_env.shape[0]
        np.testing.assert_allclose(stored_env, env[:n], rtol=1e-5, atol=1e-5)
        np.testing.assert_allclose(
            np.asarray(root["audio/mfcc"][:]), mfcc[:n], rtol=1e-4, atol=1e-3
        )
    assert not np.array_equal(
        np.asarray(default_root["audio/mfcc"][:]), np.asarray(kaiser_root["audio/mfcc"][:])
    )
    bad = run_cli("featurize", str(ingested), "--resampler", "best", check=False)
    assert bad.returncode == 1 and "unknown resampler 'best'" in bad.stderr


@pytest.mark.parametrize("res_type", ["soxr_hq", "soxr_vhq", "soxr_mq", "soxr_lq", "soxr_qq"])
def test_soxr_without_librosa_equals_librosa_resample(res_type):
    """The soxr_* path calls soxr directly (no librosa import: seconds for ``render``); every
    length and rate pair gives librosa.resample's samples exactly."""
    from dancedata.io.audio_decode import _resample

    rng = np.random.default_rng(3)
    for n in (1, 7, 1000, 44_101):
        for native, sr in ((44_100, 48_000), (48_000, 22_050), (44_100, SR), (22_050, 44_100)):
            y = rng.standard_normal(n).astype(np.float32)
            reference = librosa.resample(y, orig_sr=native, target_sr=sr, res_type=res_type)
            ours = _resample(y, native, sr, res_type)
            assert ours.dtype == np.float32 and ours.shape == reference.shape, (n, native, sr)
            np.testing.assert_array_equal(ours, reference)
