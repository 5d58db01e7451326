"""NMFD: the convolutive model against a direct sum, the KL fit, and a generated drum track whose
kick, snare and hi-hat hit times are known."""

from __future__ import annotations

import librosa
import numpy as np
import pytest
from scipy.signal import butter, find_peaks, sosfilt

from dancedata.compute.nmfd import (
    NMFD_COMPONENTS,
    initial_templates,
    kl_divergence,
    nmfd,
    nmfd_drums,
    reconstruct,
    weighted_nmfd_activation,
)
from dancedata.errors import InputError

SR = 30720
FPS = 60  # SR / hop 512


def drum_track(seconds: float = 4.0) -> tuple[np.ndarray, dict[str, np.ndarray]]:
    """Kick (pitch-dropping sine), snare (band noise + 190 Hz body), hi-hat (noise > 8 kHz) at
    120 BPM: kick on beats 1 and 3, snare on 2 and 4, hi-hat on every off-beat eighth. Returns
    the signal and each instrument's hit times in seconds."""
    rng = np.random.default_rng(0)
    n = int(SR * seconds)
    t = np.arange(int(0.3 * SR)) / SR
    kick = np.sin(2 * np.pi * np.cumsum(50 + 100 * np.exp(-t / 0.03)) / SR) * np.exp(-t / 0.12)
    band = butter(4, [300, 5000], btype="bandpass", fs=SR, output="sos")
    snare = (2 * sosfilt(band, rng.standard_normal(t.size)) + 0.5 * np.sin(2 * np.pi * 190 * t)) * (
        np.exp(-t / 0.06)
    )
    high = butter(6, 8000, btype="highpass", fs=SR, output="sos")
    hihat = 2 * sosfilt(high, rng.standard_normal(t.size)) * np.exp(-t / 0.02)
    kicks = np.arange(0.1, seconds - 0.3, 1.0)
    hits = {"kick": kicks, "snare": kicks + 0.5, "hihat": np.arange(0.35, seconds - 0.3, 0.5)}
    y = np.zeros(n)
    for name, sound in (("kick", kick), ("snare", snare), ("hihat", hihat)):
        for when in hits[name]:
            i = int(round(when * SR))
            y[i : i + sound.size] += sound[: n - i]
    return y.astype(np.float32), hits


def test_component_order_is_fixed() -> None:
    assert NMFD_COMPONENTS == ("kick", "snare", "hihat")


def test_each_activation_peaks_on_its_own_hits() -> None:
    y, hits = drum_track()
    acts = nmfd_drums(y, SR)
    assert acts.shape == (1 + y.size // 512, 3) and acts.dtype == np.float32
    for c, name in enumerate(NMFD_COMPONENTS):
        curve = acts[:, c]
        peaks, _ = find_peaks(curve, height=0.3 * curve.max(), distance=3)
        own = np.round(hits[name] * FPS).astype(int)
        assert len(peaks) == len(own), name
        assert np.max(np.abs(peaks - own)) <= 2, name
        # at the other instruments' hits this component stays quiet
        for other in NMFD_COMPONENTS:
            if other != name:
                frames = np.round(hits[other] * FPS).astype(int)
                near = max(curve[max(f - 2, 0) : f + 3].max() for f in frames)
                assert near < 0.1 * curve.max(), (name, other)


def test_reconstruct_is_the_convolutive_sum() -> None:
    rng = np.random.default_rng(0)
    w = rng.random((5, 3, 4))
    h = rng.random((3, 9))
    expected = np.zeros((5, 9))
    for k in range(5):
        for n in range(9):
            for r in range(3):
                for tau in range(4):
                    if n - tau >= 0:
                        expected[k, n] += w[k, r, tau] * h[r, n - tau]
    np.testing.assert_allclose(reconstruct(w, h), expected)


def test_known_templates_recover_sparse_activations() -> None:
    rng = np.random.default_rng(2)
    w_true = rng.random((40, 3, 5)) ** 4
    w_true /= w_true.sum(axis=(0, 2), keepdims=True)
    h_true = np.zeros((3, 80))
    onsets = {0: [5, 30, 60], 1: [15, 45], 2: [10, 25, 50, 70]}
    for r, frames in onsets.items():
        h_true[r, frames] = 10.0 + r
    v = reconstruct(w_true, h_true)
    w, h = nmfd(v, w_true, n_iter=300, update_templates=False)
    assert kl_divergence(v, reconstruct(w, h)) < 1e-3 * v.sum()
    for r, frames in onsets.items():
        top = np.sort(np.argsort(h[r])[-len(frames) :])
        np.testing.assert_array_equal(top, frames)


def test_kl_divergence_decreases() -> None:
    y, _ = drum_track(2.0)
    mag = np.abs(librosa.stft(y, n_fft=2048, hop_length=512))
    w0 = initial_templates(librosa.fft_frequencies(sr=SR, n_fft=2048), 8)
    losses = [kl_divergence(mag, reconstruct(*nmfd(mag, w0, n_iter=i))) for i in (1, 3, 10, 30)]
    assert all(b <= a * 1.0001 for a, b in zip(losses, losses[1:], strict=False))
    assert losses[-1] < 0.5 * losses[0]


def test_initial_templates_are_ordered_bands() -> None:
    freqs = librosa.fft_frequencies(sr=SR, n_fft=2048)
    w = initial_templates(freqs, 6)
    assert w.shape == (freqs.size, 3, 6)
    np.testing.assert_allclose(w.sum(axis=(0, 2)), 1.0)
    # frequency below which half of each template's energy lies
    cumulative = np.cumsum(w.sum(axis=2), axis=0)
    median = freqs[np.argmax(cumulative >= 0.5 * cumulative[-1], axis=0)]
    assert median[0] < 150 < median[1] < 5000 < median[2]
    decay = w[:, :, -1].sum(axis=0) / w[:, :, 0].sum(axis=0)
    assert decay[0] > decay[1] > decay[2]


def test_weighted_activation_and_errors() -> None:
    acts = np.array([[1.0, 0.0, 2.0], [0.0, 4.0, 0.0]], dtype=np.float32)
    np.testing.assert_allclose(weighted_nmfd_activation(acts), [3.0, 4.0])
    np.testing.assert_allclose(
        weighted_nmfd_activation(acts, {"kick": 2.0, "hihat": 0.5}), [3.0, 0.0]
    )
    np.testing.assert_allclose(weighted_nmfd_activation(acts, normalize=True), [2.0, 1.0])
    with pytest.raises(InputError, match="unknown NMFD component"):
        weighted_nmfd_activation(acts, {"tom": 1.0})
    with pytest.raises(InputError, match=r"\(frames, 3\)"):
        weighted_nmfd_activation(np.zeros((4, 2)))


def test_bad_input() -> None:
    with pytest.raises(InputError, match="non-negative"):
        nmfd(-np.ones((4, 5)), np.ones((4, 3, 2)))
    with pytest.raises(InputError, match="mono"):
        nmfd_drums(np.zeros((2, 100)), SR)


def test_silence_gives_finite_near_zero_activations() -> None:
    acts = nmfd_drums(np.zeros(SR // 2, dtype=np.float32), SR, n_iter=5)
    assert np.all(np.isfinite(acts)) and acts.max() < 1e-6


@pytest.mark.real_data
def test_components_follow_their_bands_on_a_real_drum_kit(real_data) -> None:
    """Vibe Ace's drums (offline stem): each activation tracks the spectral flux of its band."""
    from dancedata.compute.stems import separate

    path = real_data / "audio" / "Kevin_MacLeod_-_Vibe_Ace.hq.ogg"
    y, sr = librosa.load(path, sr=SR, offset=20.0, duration=8.0)
    drums = separate(y, sr)["drums"]
    acts = nmfd_drums(drums, sr)
    mag = np.abs(librosa.stft(drums, n_fft=2048, hop_length=512))
    freqs = librosa.fft_frequencies(sr=sr, n_fft=2048)

    def flux(lo: float, hi: float) -> np.ndarray:
        band = mag[(freqs >= lo) & (freqs < hi)].sum(axis=0)
        return np.maximum(np.diff(band, prepend=band[0]), 0)

    low, mid, high = flux(0, 150), flux(300, 4000), flux(7000, SR / 2)
    corr = {
        name: [float(np.corrcoef(acts[:, c], band)[0, 1]) for band in (low, mid, high)]
        for c, name in enumerate(NMFD_COMPONENTS)
    }
    assert corr["kick"][0] > 0.6 and corr["kick"][0] > corr["kick"][2]
    assert corr["snare"][1] > 0.6 and corr["snare"][1] > corr["snare"][0]
    assert corr["hihat"][2] > corr["hihat"][0]
