"""The compiled audio kernels (:mod:`dancedata.compute.jit_kernels`) against the library code
they stand in for, called directly: librosa.beat.beat_track, librosa.util.softmask, the median
network against np.median, the running median against scipy.ndimage.median_filter, and the
per-bin median of gathered frames by np.partition. Each must give the very same values."""

from __future__ import annotations

import numpy as np
import pytest

from dancedata.compute.audio_features import AudioFeatureConfig, beat_frames, onset_envelope
from dancedata.compute.jit_kernels import (
    _apply_network,
    kl_ratio,
    median_network,
    neighbour_median,
    selection_network,
)
from dancedata.compute.stems.offline import repetition_background, softmask
from dancedata.synth.music import synth_dance_music

CFG = AudioFeatureConfig()


def _envelopes() -> list[np.ndarray]:
    rng = np.random.default_rng(7)
    envs = []
    for seed, bpm in enumerate((84.0, 120.0, 151.0)):
        env = onset_envelope(synth_dance_music(bpm, 8.0, sr=CFG.sr, seed=seed), CFG)
        envs += [env, env * rng.random(env.shape).astype(np.float32)]
    envs.append(rng.random(700).astype(np.float32))
    return envs


@pytest.mark.parametrize("bpm", [None, 72.0, 120.0, 190.0])
def test_beat_frames_are_librosas_beat_track(bpm) -> None:
    import librosa.beat

    kwargs = {"start_bpm": bpm} if bpm else {}
    for env in _envelopes():
        _, want = librosa.beat.beat_track(
            onset_envelope=env,
            sr=CFG.sr,
            hop_length=CFG.hop_length,
            tightness=CFG.beat_tightness,
            units="frames",
            **kwargs,
        )
        np.testing.assert_array_equal(beat_frames(env, bpm, CFG), want)


def test_beat_frames_of_a_silent_envelope_are_none() -> None:
    assert beat_frames(np.zeros(300, np.float32), 120.0, CFG).size == 0


@pytest.mark.parametrize("dtype", [np.float32, np.float64])
@pytest.mark.parametrize("split_zeros", [True, False])
def test_softmask_is_librosas(dtype, split_zeros) -> None:
    import librosa

    rng = np.random.default_rng(3)
    x = (rng.random((64, 90)) ** 3).astype(dtype)
    ref = (rng.random((64, 90)) ** 3).astype(dtype)
    x[:4], ref[:4] = 0, 0  # both zero: the split value
    ref[4:8] = 0
    x[8:12] = 0
    x[12, :3] = ref[12, :3] = np.finfo(dtype).tiny / 4  # subnormal: below tiny, split too
    want = librosa.util.softmask(x, ref, power=2, split_zeros=split_zeros)
    got = softmask(x, ref, split_zeros)
    assert got.dtype == want.dtype
    np.testing.assert_array_equal(got, want)


def test_softmask_refuses_negative_input() -> None:
    with pytest.raises(ValueError, match="non-negative"):
        softmask(-np.ones((2, 2)), np.ones((2, 2)), True)


@pytest.mark.slow
def test_neighbour_median_is_the_partition_median_with_ties() -> None:
    rng = np.random.default_rng(5)
    frames = rng.integers(0, 4, size=(50, 33)).astype(np.float32)  # many ties
    nearest = rng.integers(0, 50, size=(20, 9))
    out = np.full_like(frames, np.nan)
    neighbour_median(frames, nearest, out, 10, median_network(9))
    want = np.partition(frames[nearest], 4, axis=1)[:, 4, :]
    np.testing.assert_array_equal(out[10:30], want)
    assert np.isnan(out[:10]).all() and np.isnan(out[30:]).all()


@pytest.mark.parametrize("k", [1, 3, 5, 9, 21, 31, 33, 41])
def test_median_network_puts_the_median_in_the_middle(k) -> None:
    rng = np.random.default_rng(k)
    values = rng.standard_normal((k, 3000)).astype(np.float32)
    values[:, :1000] = np.round(values[:, :1000])  # ties
    want = np.median(values, axis=0)
    pairs = median_network(k)
    assert (pairs[:, 0] < pairs[:, 1]).all() and pairs.max(initial=0) < k
    for a, b in pairs:
        values[a], values[b] = np.minimum(values[a], values[b]), np.maximum(values[a], values[b])
    np.testing.assert_array_equal(values[k // 2], want)


@pytest.mark.parametrize("width", [1, 7, 256])
def test_network_comparators_are_pythons_min_and_max_bit_for_bit(width) -> None:
    """Every comparator keeps what Python's ``min`` and ``max`` keep, NaN and signed zeros
    included (the compiled loop goes through a scratch row, so it vectorises); checked on the
    raw bits against the builtins applied one value at a time."""
    rng = np.random.default_rng(width)
    values = np.array([0.0, -0.0, np.nan, 1.0, -1.0, np.inf, -np.inf, 2.0], dtype=np.float32)
    pairs = median_network(9)
    for _ in range(20):
        buf = rng.choice(values, size=(9, 256)).astype(np.float32)
        want = buf.copy()
        for a, b in pairs:
            for j in range(width):
                x, y = want[a, j], want[b, j]
                want[a, j], want[b, j] = min(x, y), max(x, y)
        _apply_network(buf, pairs, width, np.empty(width, np.float32))
        np.testing.assert_array_equal(buf.view(np.uint32), want.view(np.uint32))


@pytest.mark.parametrize("order", ["C", "F"])
@pytest.mark.parametrize("axis", [0, 1])
@pytest.mark.parametrize("size", [3, 21, 31])
def test_median_filter_axis_is_scipys_median_filter(order, axis, size) -> None:
    import scipy.ndimage

    from dancedata.compute.stems.offline import median_filter_axis

    rng = np.random.default_rng(size + axis)
    mag = (rng.random((300, 333 + axis)) ** 3).astype(np.float32)  # odd and even line counts
    mag[:, :20] = np.round(mag[:, :20] * 3)  # ties
    mag = np.asarray(mag, order=order)
    sizes = [1, 1]
    sizes[axis] = size
    want = scipy.ndimage.median_filter(mag, size=tuple(sizes), mode="reflect")
    np.testing.assert_array_equal(median_filter_axis(mag, size, axis), want)


@pytest.mark.parametrize("n", [2, 6, 30])
def test_selection_network_selects_both_middle_ranks(n) -> None:
    rng = np.random.default_rng(n)
    values = np.round(rng.standard_normal((n, 2000)) * 2).astype(np.float32)
    want = np.sort(values, axis=0)[n // 2 - 1 : n // 2 + 1]
    for a, b in selection_network(n, (n // 2 - 1, n // 2)):
        values[a], values[b] = np.minimum(values[a], values[b]), np.maximum(values[a], values[b])
    np.testing.assert_array_equal(values[n // 2 - 1 : n // 2 + 1], want)
    with pytest.raises(ValueError, match="cannot select"):
        selection_network(n, (n,))


def test_repetition_background_is_the_brute_force_median_of_the_nearest_frames() -> None:
    rng = np.random.default_rng(11)
    mag = (rng.random((40, 120)) ** 2).astype(np.float32)
    width, k = 5, 7
    got = repetition_background(mag, width, neighbours=k, block=16)
    unit = mag / np.linalg.norm(mag, axis=0)
    for frame in range(mag.shape[1]):
        sim = unit[:, frame] @ unit
        sim[np.abs(np.arange(mag.shape[1]) - frame) < width] = -np.inf
        nearest = np.argsort(-sim, kind="stable")[:k]
        np.testing.assert_array_equal(got[:, frame], np.median(mag[:, nearest], axis=1))


def test_repetition_background_of_a_long_clip_takes_the_same_neighbours(monkeypatch) -> None:
    """Past the triangle's frame limit every block's full row of similarities is computed;
    the neighbours (and so the medians) are the same as from the triangle."""
    from dancedata.compute.stems import offline

    rng = np.random.default_rng(12)
    mag = (rng.random((64, 300)) ** 2).astype(np.float32)
    triangle = repetition_background(mag, 4, neighbours=9, block=32)
    monkeypatch.setattr(offline, "_TRIANGLE_FRAMES", 299)
    np.testing.assert_array_equal(repetition_background(mag, 4, neighbours=9, block=32), triangle)


def test_offline_stems_from_a_shared_stft_are_the_stems_from_the_signal() -> None:
    import librosa

    from dancedata.compute.stems import separate

    y = synth_dance_music(110.0, 3.0, sr=CFG.sr, seed=4)
    spec = librosa.stft(y, n_fft=2048, hop_length=512)
    shared, own = separate(y, CFG.sr, stft=spec), separate(y, CFG.sr)
    for name in own:
        np.testing.assert_array_equal(shared[name], own[name])
    with pytest.raises(ValueError, match="shared STFT has shape"):
        separate(y, CFG.sr, stft=spec[:, :-1])


@pytest.mark.filterwarnings("ignore:n_fft=2048 is too large")
@pytest.mark.parametrize("seconds", [0.02, 0.1, 3.0])
def test_inverse_stft_is_librosas_istft(seconds) -> None:
    import librosa

    from dancedata.compute.stems.offline import DEFAULTS as OFFLINE
    from dancedata.compute.stems.offline import InverseSTFT, stem_masks

    y = synth_dance_music(97.0, 3.0, sr=CFG.sr, seed=2)[: int(seconds * CFG.sr) + 77]
    spec = librosa.stft(y, n_fft=2048, hop_length=512)
    inverse = InverseSTFT(2048, 512, y.shape[0], spec.shape[1])
    for mask in stem_masks(np.abs(spec), CFG.sr, **OFFLINE).values():
        masked = spec * mask
        want = librosa.istft(masked, n_fft=2048, hop_length=512, length=y.shape[0])
        got = inverse(masked)
        assert got.dtype == want.dtype == np.float32
        np.testing.assert_array_equal(got, want)
        np.testing.assert_array_equal(inverse(spec, mask), want)  # the product taken per block
    double = spec.astype(np.complex128)
    want = librosa.istft(double, n_fft=2048, hop_length=512, length=y.shape[0])
    np.testing.assert_array_equal(inverse(double), want)
    with pytest.raises(ValueError, match="does not fit"):
        inverse(spec[:-1])
    with pytest.raises(ValueError, match="does not fit"):
        inverse(spec, np.ones((3, 3), dtype=np.float32))


@pytest.mark.parametrize("dtype", [np.float32, np.float64])
def test_kl_ratio_is_numpys_maximum_then_divide(dtype) -> None:
    """NMFD's V / max(Λ, ε) kernel gives numpy's two-step values exactly, tiny Λ included."""
    rng = np.random.default_rng(5)
    v = rng.random((37, 53)).astype(dtype)
    lam = (rng.random((37, 53)) * 3.0).astype(dtype)
    lam[::4] *= 1e-14  # below the floor
    lam[1, :5] = 0.0
    want = v / np.maximum(lam, 1e-12)
    got = lam.copy()
    kl_ratio(v.ravel(), got.ravel(), 1e-12)
    assert got.dtype == dtype
    np.testing.assert_array_equal(got, want)


def test_stereo_mean_is_numpys_mean_bit_for_bit() -> None:
    """The decoder's stereo downmix: np.mean's float32 bits, signed zeros included."""
    from dancedata.io.audio_decode import stereo_mean

    rng = np.random.default_rng(9)
    scale = rng.choice([1e-30, 1e-5, 1.0, 1e5], (5000, 1))
    block = (rng.standard_normal((5000, 2)) * scale).astype(np.float32)
    block[:4] = [[-0.0, -0.0], [-0.0, 0.0], [0.0, -0.0], [1e-45, -1e-45]]
    want = np.mean(block.T, axis=0)
    got = stereo_mean(block)
    assert got.dtype == want.dtype == np.float32
    np.testing.assert_array_equal(got.view(np.uint32), want.view(np.uint32))


def test_row_norms_are_numpys_column_norms_bit_for_bit() -> None:
    """REPET-SIM's frame norms from the (frames, bins) rows: np.linalg.norm(axis=0)'s bits."""
    from dancedata.compute.jit_kernels import row_norms

    rng = np.random.default_rng(10)
    mag = (rng.random((1025, 300)) ** 3).astype(np.float32)
    mag[:, 7] = 0.0
    want = np.linalg.norm(mag, axis=0)
    got = row_norms(np.ascontiguousarray(mag.T))
    assert got.dtype == want.dtype == np.float32
    np.testing.assert_array_equal(got, want)
