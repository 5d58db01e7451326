"""Per-stem FACT features against librosa called directly, and the weighted stem onset curve."""

from __future__ import annotations

import librosa
import numpy as np
import pytest

from dancedata.compute.stem_features import (
    DEFAULT_STEM_WEIGHTS,
    all_stem_features,
    n_feature_frames,
    stem_features,
    weighted_curve,
    weighted_stem_onsets,
)
from dancedata.errors import InputError

SR = 30720
HOP = 512


def _click_track(seconds: float, times: np.ndarray) -> np.ndarray:
    y = np.zeros(int(seconds * SR), dtype=np.float32)
    burst = np.random.default_rng(0).standard_normal(256) * np.exp(-np.arange(256) / 50)
    for t in times:
        i = int(round(t * SR))
        y[i : i + 256] += burst.astype(np.float32)
    return y


def test_matches_librosa_fact_recipe() -> None:
    rng = np.random.default_rng(0)
    y = (rng.standard_normal(SR * 2) * np.repeat(rng.random(20), SR // 10)).astype(np.float32)
    got = stem_features(y, SR)
    env = librosa.onset.onset_strength(y=y, sr=SR, hop_length=HOP, n_fft=2048)
    np.testing.assert_array_equal(got["onset_env"], env.astype(np.float32))
    mfcc = librosa.feature.mfcc(y=y, sr=SR, n_mfcc=20, hop_length=HOP, n_fft=2048).T
    np.testing.assert_allclose(got["mfcc"], mfcc, rtol=1e-6, atol=1e-4)
    peaks = librosa.onset.onset_detect(onset_envelope=env, sr=SR, hop_length=HOP)
    np.testing.assert_array_equal(np.flatnonzero(got["onset_peaks"]), peaks)


@pytest.mark.parametrize("n_samples", [SR, SR + 511, SR + 512, 3000])
def test_frame_count_and_dtypes(n_samples) -> None:
    y = np.random.default_rng(1).standard_normal(n_samples).astype(np.float32)
    got = stem_features(y, SR)
    a = n_feature_frames(n_samples, HOP)
    assert a == 1 + n_samples // HOP
    assert got["onset_env"].shape == (a,) and got["onset_env"].dtype == np.float32
    assert got["mfcc"].shape == (a, 20) and got["mfcc"].dtype == np.float32
    assert got["onset_peaks"].shape == (a,) and got["onset_peaks"].dtype == np.uint8


def test_onset_peaks_land_on_clicks() -> None:
    times = np.arange(0.25, 3.0, 0.5)
    got = stem_features(_click_track(3.0, times), SR)
    peaks = np.flatnonzero(got["onset_peaks"])
    expected = np.round(times * SR / HOP).astype(int)
    assert len(peaks) == len(expected)
    assert np.max(np.abs(peaks - expected)) <= 1


def test_silent_stem_has_no_onsets() -> None:
    got = stem_features(np.zeros(SR, dtype=np.float32), SR)
    assert not np.any(got["onset_env"]) and not np.any(got["onset_peaks"])
    assert np.all(np.isfinite(got["mfcc"]))


def test_all_stems_and_weighted_onsets() -> None:
    stems = {
        "drums": _click_track(2.0, np.array([0.5, 1.5])),
        "bass": np.zeros(2 * SR, dtype=np.float32),
        "vocals": _click_track(2.0, np.array([1.0])),
        "other": _click_track(2.0, np.array([0.25])),
    }
    feats = all_stem_features(stems, SR)
    assert set(feats) == set(stems)
    onsets = {name: f["onset_env"] for name, f in feats.items()}
    weights = {"drums": 0.5, "bass": 0.2, "vocals": 0.2, "other": 0.1}
    curve = weighted_stem_onsets(onsets, weights)
    expected = sum(w * onsets[name].astype(np.float64) for name, w in weights.items())
    np.testing.assert_allclose(curve, expected, rtol=1e-6)
    assert curve.dtype == np.float32
    default = weighted_stem_onsets(onsets)
    np.testing.assert_allclose(default, sum(onsets.values()), rtol=1e-6)
    assert set(DEFAULT_STEM_WEIGHTS) == set(stems)


def test_weighted_curve_normalize_and_errors() -> None:
    curves = {"a": np.array([0.0, 2.0, 4.0]), "b": np.array([1.0, 0.0, 0.0]), "z": np.zeros(3)}
    np.testing.assert_allclose(
        weighted_curve(curves, {"a": 1.0, "b": 2.0, "z": 5.0}, normalize=True), [2.0, 0.5, 1.0]
    )
    # a weight of 0 needs no curve
    np.testing.assert_allclose(weighted_curve(curves, {"a": 1.0, "nope": 0.0}), [0, 2, 4])
    with pytest.raises(InputError, match="missing: nope"):
        weighted_curve(curves, {"nope": 1.0})
    with pytest.raises(InputError, match="one length"):
        weighted_curve({"a": np.zeros(3), "b": np.zeros(4)}, {"a": 1.0})


def test_rejects_non_mono() -> None:
    with pytest.raises(InputError, match="mono"):
        stem_features(np.zeros((2, 100)), SR)
