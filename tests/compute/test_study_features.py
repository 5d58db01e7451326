"""Feature sets of the other studies: against librosa called directly and frame-count formulas."""

from __future__ import annotations

import math

import librosa
import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from dancedata.compute.study_features import (
    choreograph_mel,
    frames_per_chunk,
    hop_for_fps,
    local_tempo,
    stft_per_motion_frame,
    tempogram,
    tempogram_bpms,
)
from dancedata.errors import InputError

SR = 30720


def _noise(seconds: float, sr: int = SR, seed: int = 0) -> np.ndarray:
    return np.random.default_rng(seed).standard_normal(int(seconds * sr)).astype(np.float32)


def test_choreograph_mel_is_librosa_at_one_hop_per_motion_frame() -> None:
    y = _noise(1.5)
    got = choreograph_mel(y, SR)  # 60 fps → hop 512
    ref = librosa.power_to_db(librosa.feature.melspectrogram(y=y, sr=SR, hop_length=512, n_mels=96))
    assert got.shape == (1 + y.size // 512, 96) and got.dtype == np.float32
    np.testing.assert_allclose(got, ref.T, rtol=1e-5, atol=1e-3)
    power = choreograph_mel(y, SR, db=False)
    np.testing.assert_allclose(10 * np.log10(np.maximum(power, 1e-10)), got, atol=1e-3)


def test_choreograph_mel_resamples_when_the_hop_is_not_whole() -> None:
    y = _noise(2.0, sr=22050)
    assert hop_for_fps(22050, 60) == (22080, 368)
    got = choreograph_mel(y, 22050, fps=60)
    n = librosa.resample(y, orig_sr=22050, target_sr=22080, res_type="soxr_hq").size
    assert got.shape == (1 + n // 368, 96)
    # 2 s at 60 fps → frames at i/60 s for i = 0..120
    assert got.shape[0] == 121


@settings(max_examples=100, deadline=None)
@given(sr=st.integers(8000, 96000), fps=st.sampled_from([20.0, 24.0, 25.0, 30.0, 60.0, 120.0]))
def test_hop_for_fps_gives_exact_frame_rate(sr, fps) -> None:
    rate, hop = hop_for_fps(sr, fps)
    assert rate / hop == pytest.approx(fps, rel=1e-12)
    assert rate >= sr and hop == math.ceil(sr / fps)


@pytest.mark.parametrize(
    ("target_sr", "fps", "k"),
    [(16000, 30.0, 3), (32000, 30.0, 6), (16000, 15.0, 6), (16000, 20.0, 5)],
)
def test_frames_per_chunk_formula(target_sr, fps, k) -> None:
    chunk = round(target_sr / fps)
    assert frames_per_chunk(chunk, 200) == k == 1 + chunk // 200
    y = _noise(1.0, sr=SR)
    got = stft_per_motion_frame(y, SR, fps=fps, target_sr=target_sr)
    assert got.shape == (math.ceil(fps), 1025, k)
    assert got.reshape(got.shape[0], -1).shape[1] == 1025 * k  # 6150 when k = 6


@pytest.mark.filterwarnings("ignore:n_fft=2048 is too large")
def test_stft_per_motion_frame_is_librosa_on_each_chunk() -> None:
    y16 = _noise(0.5, sr=16000, seed=3)
    got = stft_per_motion_frame(y16, 16000, fps=30.0, target_sr=16000)
    assert got.shape == (15, 1025, 3)
    for i in (0, 7, 14):
        start = round(i * 16000 / 30)
        chunk = np.zeros(533, dtype=np.float32)
        piece = y16[start : start + 533]
        chunk[: piece.size] = piece
        ref = np.abs(librosa.stft(chunk, n_fft=2048, hop_length=200))
        np.testing.assert_allclose(got[i], ref, rtol=1e-5, atol=1e-5)


@pytest.mark.filterwarnings("ignore:n_fft=2048 is too large")
def test_stft_per_motion_frame_resamples_to_16k_and_honours_n_frames() -> None:
    y = _noise(1.0, sr=SR)
    got = stft_per_motion_frame(y, SR, fps=30.0, n_frames=10)
    y16 = librosa.resample(y, orig_sr=SR, target_sr=16000, res_type="soxr_hq")
    ref = np.abs(librosa.stft(y16[533 * 4 + 1 : 533 * 4 + 1 + 533], n_fft=2048, hop_length=200))
    assert got.shape == (10, 1025, 3)
    np.testing.assert_allclose(got[4], ref, rtol=1e-4, atol=1e-4)  # chunk 4 starts at 2133
    with pytest.raises(InputError, match="motion frame"):
        stft_per_motion_frame(y, SR, n_frames=0)


def test_tempogram_is_librosa_at_feature_rate() -> None:
    y = _noise(3.0)
    env = librosa.onset.onset_strength(y=y, sr=SR, hop_length=512)
    ref = librosa.feature.tempogram(onset_envelope=env, sr=SR, hop_length=512, win_length=384)
    got = tempogram(y, SR)
    assert got.shape == (1 + y.size // 512, 384) and got.dtype == np.float32
    np.testing.assert_allclose(got, ref.T, rtol=1e-5, atol=1e-6)
    np.testing.assert_allclose(tempogram(onset_envelope=env, sr=SR), got)
    with pytest.raises(InputError):
        tempogram(sr=SR)


def test_tempogram_finds_a_click_tempo() -> None:
    y = np.zeros(8 * SR, dtype=np.float32)
    for t in np.arange(0.0, 8.0, 0.5):  # 120 BPM
        i = int(t * SR)
        y[i : i + 64] = 1.0
    tempo = local_tempo(tempogram(y, SR), SR)
    middle = tempo[2 * 60 : 6 * 60]
    assert np.median(middle) == pytest.approx(120.0, rel=0.03)
    np.testing.assert_allclose(tempogram_bpms(4, SR)[1:], [3600.0, 1800.0, 1200.0])


@pytest.mark.real_data
def test_tempogram_of_snare_accelerate_rises_with_the_onset_rate(real_data) -> None:
    """Independent reference: the tempo implied by the spacing of detected snare hits."""
    from scipy.stats import spearmanr

    y, sr = librosa.load(real_data / "audio" / "snare-accelerate.ogg", sr=SR)
    tempo = local_tempo(tempogram(y, sr), sr)
    onsets = librosa.onset.onset_detect(y=y, sr=sr, hop_length=512, units="time")
    between = (onsets[:-1] + onsets[1:]) / 2
    ioi_bpm = 60.0 / np.diff(onsets)
    inner = (between > 4.0) & (between < 26.0)  # away from the clip edges
    assert inner.sum() > 20
    frames = np.round(between[inner] * 60).astype(int)
    ratio = tempo[frames] / ioi_bpm[inner]
    assert np.median(np.abs(ratio - 1)) < 0.1
    rho = spearmanr(np.arange(tempo.size)[::30], tempo[::30]).statistic
    assert rho > 0.95
    assert tempo[: 3 * 60].mean() < 50 and tempo[-3 * 60 :].mean() > 150
