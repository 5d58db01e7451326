"""``compute.constant_q.cqt_magnitude`` against ``librosa.cqt`` called directly: identical
arrays on real music and synthetic tracks, with and without early sub-sampling, on a first call
(banks built) and on later calls (banks reused); the bank cache stays bounded."""

from __future__ import annotations

import warnings

import numpy as np
import pytest

from dancedata.compute import constant_q
from dancedata.compute.constant_q import cqt_magnitude

SR = 30720


def _librosa(y: np.ndarray, sr: float, hop: int, n_bins: int, bpo: int, tuning: float, fmin=None):  # noqa: ANN001
    import librosa

    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return np.abs(
            librosa.cqt(
                y,
                sr=sr,
                hop_length=hop,
                fmin=fmin,
                n_bins=n_bins,
                bins_per_octave=bpo,
                tuning=tuning,
            )
        )


def _synth(seconds: float, seed: int) -> np.ndarray:
    from dancedata.synth.music import synth_dance_music

    return synth_dance_music(120.0 + seed, seconds, sr=SR, seed=seed).astype(np.float32)


@pytest.mark.parametrize("tuning", [0.0, -0.07, 0.23])
def test_chroma_cens_cqt_equals_librosa_first_and_cached(tuning):
    constant_q._BANKS.clear()
    for seed in (1, 2):  # the second track reuses the first one's banks
        y = _synth(6.0, seed)
        want = _librosa(y, SR, 512, 252, 36, tuning)
        got = cqt_magnitude(y, SR, 512, n_bins=252, bins_per_octave=36, tuning=tuning)
        assert got.dtype == want.dtype and got.shape == want.shape
        assert got.tobytes() == want.tobytes()
    assert 0 < len(constant_q._BANKS) <= 7


def test_early_subsampling_and_float64_equal_librosa():
    y = _synth(4.0, 3)
    # two octaves from C2 at hop 512: the top filter is far below Nyquist, so librosa first
    # halves the signal several times
    fmin = 65.40639132514966
    for signal in (y, y.astype(np.float64)):
        want = _librosa(signal, SR, 512, 24, 12, 0.1, fmin=fmin)
        got = cqt_magnitude(signal, SR, 512, n_bins=24, bins_per_octave=12, tuning=0.1, fmin=fmin)
        assert got.tobytes() == want.tobytes()


def test_bank_cache_is_bounded():
    constant_q._BANKS.clear()
    y = _synth(2.0, 4)
    for k in range(4):
        cqt_magnitude(y, SR, 512, n_bins=252, bins_per_octave=36, tuning=-0.5 + 0.01 * k)
    assert len(constant_q._BANKS) == constant_q.BANKS_KEPT
    with pytest.raises(ValueError):
        cqt_magnitude(np.zeros((2, 100), np.float32), SR, 512, 252, 36, 0.0)


@pytest.mark.real_data
def test_vibe_ace_cqt_equals_librosa(real_data):
    import librosa

    path = real_data / "audio" / "Kevin_MacLeod_-_Vibe_Ace.hq.ogg"
    y, _ = librosa.load(path, sr=SR, duration=20)
    tuning = float(librosa.estimate_tuning(y=y, sr=SR, bins_per_octave=36))
    for _ in range(2):
        got = cqt_magnitude(y, SR, 512, n_bins=252, bins_per_octave=36, tuning=tuning)
        assert got.tobytes() == _librosa(y, SR, 512, 252, 36, tuning).tobytes()


@pytest.mark.parametrize("resolution", [0.01, 0.0005])
def test_tuning_from_the_pitch_band_is_librosas_estimate_tuning(resolution):
    # a fine resolution makes the histogram's peak sensitive to every picked pitch
    import librosa

    rng = np.random.default_rng(9)
    for seed in range(4):
        mag = np.abs(librosa.stft(_synth(5.0, seed), n_fft=2048, hop_length=512))
        for spectrum in (mag, mag * rng.random(mag.shape, dtype=np.float32)):
            want = librosa.estimate_tuning(
                S=spectrum, sr=SR, n_fft=2048, resolution=resolution, bins_per_octave=36
            )
            got = constant_q.estimate_tuning_from_magnitude(
                spectrum, SR, 2048, bins_per_octave=36, resolution=resolution
            )
            assert got == want
    with pytest.raises(ValueError, match="is not a 2048-point"):
        constant_q.estimate_tuning_from_magnitude(mag[1:], SR, 2048, bins_per_octave=36)
