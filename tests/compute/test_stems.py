"""Stem separation: the dispatcher and the weight-free ``offline`` backend.

Known answers come from generated signals (a sustained low sine is bass, clicks are drums, a
never-repeating glide is "vocals", a steady tone is "other") and from the masks' construction:
the four stems must add back to the input.
"""

from __future__ import annotations

import json
import subprocess
import sys

import numpy as np
import pytest

from dancedata.compute.stems import (
    STEM_BACKENDS,
    STEM_NAMES,
    backend_config,
    separate,
)
from dancedata.compute.stems import offline as stems_offline
from dancedata.errors import InputError

SR = 30720


def _energy(x: np.ndarray) -> float:
    return float(np.sum(np.asarray(x, dtype=np.float64) ** 2))


def _corr(a: np.ndarray, b: np.ndarray) -> float:
    return float(np.corrcoef(a, b)[0, 1])


def _clicks(n: int, times_s: np.ndarray, sr: int = SR) -> np.ndarray:
    """Short decaying noise bursts (5 ms) at the given times."""
    rng = np.random.default_rng(1)
    out = np.zeros(n)
    burst = rng.standard_normal(int(0.005 * sr)) * np.exp(-np.arange(int(0.005 * sr)) / 40)
    for t in times_s:
        i = int(t * sr)
        out[i : i + burst.size] += burst[: n - i]
    return out


def test_backend_and_stem_names_are_the_contract() -> None:
    assert STEM_NAMES == ("drums", "bass", "vocals", "other")
    assert STEM_BACKENDS == ("offline", "openunmix")


def test_offline_stems_sum_to_input_and_keep_shape() -> None:
    t = np.arange(2 * SR) / SR
    y = (0.3 * np.sin(2 * np.pi * 80 * t) + _clicks(t.size, np.arange(0.1, 2, 0.25))).astype(
        np.float32
    )
    stems = separate(y, SR, backend="offline", repeat_seconds=0.5)
    assert tuple(stems) == STEM_NAMES
    for stem in stems.values():
        assert stem.shape == y.shape and stem.dtype == np.float32
    total = np.sum(list(stems.values()), axis=0)
    np.testing.assert_allclose(total, y, atol=1e-5 * np.abs(y).max())


def test_offline_sends_sustained_bass_to_bass_and_clicks_to_drums() -> None:
    t = np.arange(3 * SR) / SR
    bass = 0.3 * np.sin(2 * np.pi * 70 * t)
    clicks = _clicks(t.size, np.arange(0.1, 3, 0.3))
    stems = separate((bass + clicks).astype(np.float32), SR, repeat_seconds=0.5)
    assert _corr(stems["bass"], bass) > 0.95
    assert _corr(stems["drums"], clicks) > 0.8
    # most of the click energy is in drums, little of the bass sine is
    assert _energy(stems["drums"]) > 0.6 * _energy(clicks)
    assert _energy(stems["drums"]) < 0.2 * (_energy(bass) + _energy(clicks))


def test_offline_novel_mid_band_goes_to_vocals_and_steady_tone_to_other() -> None:
    t = np.arange(4 * SR) / SR
    steady = 0.2 * np.sin(2 * np.pi * 1000 * t)
    # a glide 400 → 2400 Hz: every frame's spectrum differs from all others (never repeats)
    glide = 0.2 * np.sin(2 * np.pi * (400 * t + 250 * t**2))
    stems = separate((steady + glide).astype(np.float32), SR, repeat_seconds=0.5)
    assert _corr(stems["vocals"], glide) > 0.7
    assert _corr(stems["other"], steady) > 0.7
    assert _corr(stems["vocals"], glide) > _corr(stems["vocals"], steady)


def test_repetition_background_is_median_of_nearest_distant_frames() -> None:
    """Against a brute-force reference: sort all frames by cosine similarity, skip those within
    ``width`` frames, take the median of the first k."""
    rng = np.random.default_rng(3)
    mag = rng.random((20, 60)).astype(np.float32)
    width, k = 4, 7
    got = stems_offline.repetition_background(mag, width, neighbours=k, block=16)
    unit = mag / np.linalg.norm(mag, axis=0)
    for i in range(mag.shape[1]):
        sim = unit[:, i] @ unit
        far = np.abs(np.arange(mag.shape[1]) - i) >= width
        order = [j for j in np.argsort(-sim, kind="stable") if far[j]][:k]
        np.testing.assert_allclose(got[:, i], np.median(mag[:, order], axis=1), rtol=1e-6)


def test_repetition_background_of_a_too_short_clip_is_the_clip() -> None:
    mag = np.random.default_rng(0).random((5, 6)).astype(np.float32)
    np.testing.assert_array_equal(stems_offline.repetition_background(mag, width=4), mag)


def test_lowpass_weight_is_half_at_cutoff() -> None:
    w = stems_offline.lowpass_weight(np.array([0.0, 200.0, 2000.0]), 200.0, 4)
    np.testing.assert_allclose(w, [1.0, 0.5, 1 / (1 + 10.0**8)])


def test_stereo_input_gives_mono_stems_of_the_downmix() -> None:
    t = np.arange(SR) / SR
    left = np.sin(2 * np.pi * 70 * t)
    right = _clicks(t.size, np.array([0.2, 0.6]))
    stems = separate(np.stack([left, right]).astype(np.float32), SR, repeat_seconds=0.25)
    total = np.sum(list(stems.values()), axis=0)
    np.testing.assert_allclose(total, (left + right) / 2, atol=1e-5)


def test_integer_pcm_is_scaled_to_full_scale_one() -> None:
    from dancedata.compute.stems import check_audio

    pcm = np.array([0, 16384, -32767, 32767], dtype=np.int16)
    np.testing.assert_allclose(check_audio(pcm, SR), pcm / 32767.0, rtol=1e-6)
    with pytest.raises(InputError, match="dtype"):
        check_audio(np.array(["a", "b"]), SR)


def test_silence_gives_silent_stems() -> None:
    stems = separate(np.zeros(SR // 2, dtype=np.float32), SR)
    assert all(np.all(s == 0) for s in stems.values())


@pytest.mark.parametrize(
    ("y", "sr", "kwargs", "message"),
    [
        (np.zeros(100), SR, {"backend": "demucs"}, "unknown stem backend"),
        (np.zeros(100), SR, {"hpss_kernell": 3}, "unknown option"),
        (np.array([0.0, np.nan, 0.0]), SR, {}, "NaN"),
        (np.zeros(0), SR, {}, "empty"),
        (np.zeros((3, 4, 5)), SR, {}, "shape"),
        (np.zeros(100), 0, {}, "sample rate"),
    ],
)
def test_bad_input_raises_input_error(y, sr, kwargs, message) -> None:
    with pytest.raises(InputError, match=message):
        separate(y, sr, **kwargs)


def test_backend_config_names_every_setting() -> None:
    config = backend_config("offline", bass_cutoff_hz=150.0)
    assert config["backend"] == "offline" and config["bass_cutoff_hz"] == 150.0
    assert set(config) == {"backend", *stems_offline.DEFAULTS}
    json.dumps(config)  # goes into manifests and Zarr attrs as is


def test_openunmix_weight_targets_are_the_stem_names_in_order() -> None:
    """io's weight lookup names its four targets itself (io imports nothing of compute); they
    must be the stems every backend returns, in the same order (missing files are listed so)."""
    from dancedata.io.openunmix_weights import MODELS, TARGETS

    assert TARGETS == STEM_NAMES
    assert all(set(spec["files"]) == set(STEM_NAMES) for spec in MODELS.values())


@pytest.mark.slow
def test_importing_and_offline_separation_never_import_torch() -> None:
    code = (
        "import sys, numpy as np, dancedata\n"
        "from dancedata.compute import stems, stem_features, nmfd, study_features\n"
        "stems.separate(np.zeros(4096, dtype=np.float32), 30720)\n"
        "stems.backend_config('openunmix')\n"
        "print(any(m == 'torch' or m.startswith('torch.') for m in sys.modules))\n"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.strip() == "False"


@pytest.mark.real_data
def test_offline_drums_of_snare_accelerate_carry_the_energy_and_the_onsets(real_data) -> None:
    import librosa

    path = real_data / "audio" / "snare-accelerate.ogg"
    y, sr = librosa.load(path, sr=SR, offset=10.0, duration=8.0)
    stems = separate(y, sr)
    assert _energy(stems["drums"]) > 0.8 * _energy(y)
    np.testing.assert_allclose(np.sum(list(stems.values()), axis=0), y, atol=1e-5)
    # every onset of the mix is an onset of the drums stem too (within 2 frames at 60 fps)
    mix_on = librosa.onset.onset_detect(y=y, sr=sr, hop_length=512)
    drum_on = librosa.onset.onset_detect(y=stems["drums"], sr=sr, hop_length=512)
    assert len(mix_on) >= 8
    misses = [f for f in mix_on if np.min(np.abs(drum_on - f)) > 2]
    assert len(misses) <= len(mix_on) // 10


@pytest.mark.real_data
def test_offline_stems_of_vibe_ace_are_band_limited_where_they_should_be(real_data) -> None:
    import librosa

    path = real_data / "audio" / "Kevin_MacLeod_-_Vibe_Ace.hq.ogg"
    y, sr = librosa.load(path, sr=SR, offset=20.0, duration=6.0)
    stems = separate(y, sr)
    np.testing.assert_allclose(np.sum(list(stems.values()), axis=0), y, atol=1e-5)
    freqs = librosa.fft_frequencies(sr=sr, n_fft=2048)
    power = {name: np.abs(librosa.stft(s)) ** 2 for name, s in stems.items()}

    def below(name: str, hz: float) -> float:
        return float(power[name][freqs < hz].sum() / power[name].sum())

    assert below("bass", 300) > 0.98
    assert below("vocals", 120) < 0.02 and below("vocals", 5000) > 0.95
    assert below("other", 120) < 0.02
