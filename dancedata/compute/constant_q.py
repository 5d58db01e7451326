"""Constant-Q magnitude of a signal with its filter banks kept between tracks.

The same algorithm and the same numbers as ``librosa.cqt`` (librosa 0.11: Schörkhuber & Klapuri's
recursive sub-sampling, one octave of wavelet filters applied to an STFT at a time, the signal
halved by soxr between octaves, lengths scaled), computed from librosa's public building blocks.
What differs is only that the frequency-domain filter bank of each octave, which depends on the
sample rate, the tuning and the bin layout but not on the signal, is built once and reused:
building it (wavelets, their FFTs, sparsification) was half of the chroma_cens time of a track.
The tuning that ``estimate_tuning`` returns lies on a grid of 0.01 bins, so tracks share banks
(the synthetic AIST++ songs have four tunings between them); at most :data:`BANKS_KEPT` banks
are kept per process.

Equality with ``librosa.cqt`` is tested on real and synthetic music
(tests/compute/test_constant_q.py): identical arrays.
"""

from __future__ import annotations

from collections import OrderedDict
from typing import Any

import numpy as np

__all__ = ["BANKS_KEPT", "cqt_magnitude"]

BANKS_KEPT = 16
_BANKS: OrderedDict[tuple[Any, ...], tuple[Any, int]] = OrderedDict()


def _two_factors(x: int) -> int:
    count = 0
    while x > 0 and x % 2 == 0:
        count += 1
        x //= 2
    return count


def _octave_bank(
    sr: float, freqs: np.ndarray, alpha: np.ndarray, rescale: float, sparsity: float, dtype: Any
) -> tuple[Any, int]:
    """The sparse (filters, n_fft // 2 + 1) frequency-domain bank of one octave and its n_fft,
    rescaled by ``rescale`` (librosa's compensation for the octave's sub-sampling); cached."""
    import librosa

    key = (
        float(sr),
        freqs.tobytes(),
        alpha.tobytes(),
        float(rescale),
        sparsity,
        np.dtype(dtype).str,
    )
    hit = _BANKS.get(key)
    if hit is not None:
        _BANKS.move_to_end(key)
        return hit
    basis, lengths = librosa.filters.wavelet(
        freqs=freqs, sr=sr, filter_scale=1, norm=1, pad_fft=True, window="hann", gamma=0,
        alpha=alpha,  # type: ignore[arg-type]  # librosa takes per-bin alphas; its stub says float
    )  # fmt: skip
    n_fft = basis.shape[1]
    basis *= lengths[:, np.newaxis] / float(n_fft)
    fft_basis = librosa.get_fftlib().fft(basis, n=n_fft, axis=1)[:, : (n_fft // 2) + 1]
    fft_basis = librosa.util.sparsify_rows(fft_basis, quantile=sparsity, dtype=dtype)
    fft_basis[:] *= rescale  # a numpy float64, as librosa's np.sqrt gives
    _BANKS[key] = (fft_basis, n_fft)
    while len(_BANKS) > BANKS_KEPT:
        _BANKS.popitem(last=False)
    return fft_basis, n_fft


def _relative_bandwidth(freqs: np.ndarray) -> np.ndarray:
    """Each bin's bandwidth relative to its frequency, from the local bins per octave (centred
    differences of log2 f, one-sided at the ends), as librosa's wavelet filters define it."""
    bpo = np.empty_like(freqs)
    logf = np.log2(freqs)
    bpo[0] = 1 / (logf[1] - logf[0])
    bpo[-1] = 1 / (logf[-1] - logf[-2])
    bpo[1:-1] = 2 / (logf[2:] - logf[:-2])
    return (2.0 ** (2 / bpo) - 1) / (2.0 ** (2 / bpo) + 1)


def cqt_magnitude(
    y: np.ndarray,
    sr: float,
    hop_length: int,
    n_bins: int,
    bins_per_octave: int,
    tuning: float,
    fmin: float | None = None,
    sparsity: float = 0.01,
) -> np.ndarray:
    """|CQT| (n_bins, frames) of mono ``y`` at ``sr`` Hz: ``np.abs(librosa.cqt(y, sr=sr,
    hop_length=hop_length, fmin=fmin, n_bins=n_bins, bins_per_octave=bins_per_octave,
    tuning=tuning))`` with librosa's other defaults (Hann wavelets, filter_scale 1, L1 norm,
    sparsity 0.01, lengths scaled, constant padding, soxr_hq), ``fmin`` None meaning C1."""
    import librosa

    y = np.asarray(y)
    if y.ndim != 1 or n_bins < 2:
        raise ValueError(f"cqt_magnitude needs mono audio and 2+ bins, got {y.shape}, {n_bins}")
    n_octaves = int(np.ceil(float(n_bins) / bins_per_octave))
    n_filters = min(bins_per_octave, n_bins)
    base_hz = float(librosa.note_to_hz("C1")) if fmin is None else fmin
    fmin = base_hz * 2.0 ** (tuning / bins_per_octave)
    freqs = librosa.interval_frequencies(
        n_bins=n_bins, fmin=fmin, intervals="equal", bins_per_octave=bins_per_octave, sort=True
    )
    alpha = _relative_bandwidth(freqs)
    lengths, cutoff = librosa.filters.wavelet_lengths(
        freqs=freqs, sr=sr, window="hann", filter_scale=1, gamma=0, alpha=alpha
    )
    nyquist = sr / 2.0
    if cutoff > nyquist:
        raise ValueError(f"CQT filters reach {cutoff:.0f} Hz, above the Nyquist {nyquist:.0f} Hz")
    dtype = librosa.util.dtype_r2c(y.dtype)
    # early sub-sampling, when the top octave leaves room and the hop has factors of two
    first = max(0, int(np.ceil(np.log2(nyquist / cutoff)) - 1) - 1)
    count = min(first, max(0, _two_factors(hop_length) - n_octaves + 1))
    if count > 0:
        factor = 2**count
        hop_length //= factor
        if y.shape[-1] < factor:
            raise ValueError(f"signal of {len(y)} samples too short for a {n_octaves}-octave CQT")
        y = librosa.resample(y, orig_sr=factor, target_sr=1, res_type="soxr_hq", scale=True)
        sr = sr / float(factor)
    responses = []
    my_y, my_sr, my_hop = y, sr, hop_length
    for i in range(n_octaves):
        sl = slice(-n_filters, None) if i == 0 else slice(-n_filters * (i + 1), -n_filters * i)
        bank, n_fft = _octave_bank(
            my_sr, freqs[sl], alpha[sl], np.sqrt(sr / my_sr), sparsity, dtype
        )
        spectrum = librosa.stft(
            my_y, n_fft=n_fft, hop_length=my_hop, window="ones", pad_mode="constant", dtype=dtype
        )
        responses.append(bank.dot(spectrum))
        if my_hop % 2 == 0:
            my_hop //= 2
            my_sr /= 2.0
            my_y = librosa.resample(my_y, orig_sr=2, target_sr=1, res_type="soxr_hq", scale=True)
    frames = min(r.shape[-1] for r in responses)
    out = np.empty((n_bins, frames), dtype=dtype, order="F")
    end = n_bins
    for response in responses:  # octaves from the top down
        n_oct = response.shape[-2]
        if end < n_oct:
            out[:end] = response[-end:, :frames]
        else:
            out[end - n_oct : end] = response[:, :frames]
        end -= n_oct
    lengths, _ = librosa.filters.wavelet_lengths(
        freqs=freqs, sr=sr, window="hann", filter_scale=1, gamma=0, alpha=alpha
    )
    out /= np.sqrt(lengths)[:, np.newaxis]
    return np.abs(out)


def estimate_tuning_from_magnitude(
    mag: np.ndarray, sr: float, n_fft: int, bins_per_octave: int, resolution: float = 0.01
) -> float:
    """``librosa.estimate_tuning(S=mag, sr=sr, n_fft=n_fft, bins_per_octave=...)`` (piptrack's
    defaults: 150-4000 Hz, threshold 0.1), the same value, on the bins of the pitch band only.

    piptrack interpolates, differentiates and picks local maxima over every bin, then keeps
    those from 150 Hz to 4 kHz (a quarter of them at sr 30720, n_fft 2048). Each of those steps
    reads a bin's two neighbours, so the band plus one bin either side gives the band's values
    exactly; only the per-frame maximum (the 0.1 threshold's reference) needs every bin. The
    pitches and magnitudes of the picked bins are librosa's (its own interpolation kernel, the
    same dtype promotions), and the median and histogram after them do not depend on order.
    """
    import librosa
    from librosa.core.pitch import _parabolic_interpolation

    spectrum = np.abs(np.asarray(mag))
    if spectrum.ndim != 2 or spectrum.shape[0] != 1 + n_fft // 2:
        raise ValueError(f"magnitude of shape {spectrum.shape} is not a {n_fft}-point |STFT|")
    freqs = librosa.fft_frequencies(sr=sr, n_fft=n_fft)
    in_band = np.flatnonzero((freqs >= 150.0) & (freqs < min(4000.0, float(sr) / 2)))
    if in_band.size == 0 or in_band[0] < 1 or in_band[-1] > freqs.size - 2:
        return float(
            librosa.estimate_tuning(
                S=mag, sr=sr, n_fft=n_fft, resolution=resolution, bins_per_octave=bins_per_octave
            )
        )
    lo, hi = int(in_band[0]) - 1, int(in_band[-1]) + 2  # one neighbour each side
    band = spectrum[lo:hi]
    avg = np.gradient(band, axis=-2)
    shift = _parabolic_interpolation(band, axis=-2)
    dskew = 0.5 * avg * shift
    ref_value = 0.1 * np.max(spectrum, axis=-2, keepdims=True)
    peaks = librosa.util.localmax(band * (band > ref_value), axis=-2)
    peaks[0] = peaks[-1] = False  # the neighbours are outside the band
    rows, cols = np.nonzero(peaks)
    pitch = np.asarray((rows + lo + shift[rows, cols]) * float(sr) / n_fft, dtype=spectrum.dtype)
    level = (band[rows, cols] + dskew[rows, cols]).astype(spectrum.dtype)
    keep = pitch > 0
    threshold = np.median(level[keep]) if keep.any() else 0.0
    return float(
        librosa.pitch_tuning(
            pitch[(level >= threshold) & keep],
            resolution=resolution,
            bins_per_octave=bins_per_octave,
        )
    )
