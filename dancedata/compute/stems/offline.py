"""Weight-free approximate stem separation: HPSS, frequency bands and a repetition mask.

This is **not** a trained separator. It splits the short-time spectrum with four soft masks that
sum to one in every time-frequency bin, so the four stems sum back to the input (up to float
rounding of the inverse STFT):

* **drums** = percussive part of harmonic/percussive source separation (median filtering,
  Fitzgerald 2010; the masks of ``librosa.decompose.hpss``, see :func:`hpss_masks`): broadband,
  short events.
* **bass** = harmonic part below ``bass_cutoff_hz`` (Butterworth-shaped crossover).
* **vocals** = harmonic part in the vocal band (``bass_cutoff_hz`` to ``vocal_high_hz``) that does
  *not* repeat: the REPET-SIM idea (Rafii & Pardo 2012, ``librosa.decompose.nn_filter``) that
  accompaniment repeats and a voice mostly does not.
* **other** = the remaining harmonic energy (repeating mid band and everything above the vocal
  band).

What to expect: drums are usually good (percussion is what HPSS isolates well); bass is "low
harmonic energy", so a kick drum's tail or a low piano note lands there too; vocals is "novel
mid-band harmonic energy", so a lead instrument (sax, synth lead) lands there as well as a voice.
For the real thing use the ``openunmix`` backend.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from dancedata.compute.stems.base import STEM_NAMES, to_mono
from dancedata.compute.thread_pools import one_thread

DEFAULTS: dict[str, Any] = {
    "n_fft": 2048,
    "hop_length": 512,
    "hpss_kernel": 31,
    "bass_cutoff_hz": 200.0,
    "vocal_high_hz": 4000.0,
    "crossover_order": 4,
    "repeat_seconds": 2.0,
    "repeat_neighbours": 21,
    "vocal_margin": 2.0,
}


def lowpass_weight(freqs_hz: np.ndarray, cutoff_hz: float, order: int) -> np.ndarray:
    """Butterworth-shaped power response 1 / (1 + (f / fc)^(2·order)), in [0, 1]; 0.5 at fc."""
    ratio = np.asarray(freqs_hz, dtype=np.float64) / float(cutoff_hz)
    return 1.0 / (1.0 + ratio ** (2 * int(order)))


def median_filter_axis(values: np.ndarray, size: int, axis: int) -> np.ndarray:
    """Running median of ``size`` values along ``axis`` of a 2-d array, edges mirrored.

    Equal to ``scipy.ndimage.median_filter`` with ``size`` along ``axis``, 1 along the other axis
    and ``mode="reflect"`` (a median selects one of the values, so the results are identical),
    and several times faster than SciPy's 1-d running-order filter on every line: the lines are
    laid side by side with ``size // 2`` mirrored values at both ends, and the output rows come
    from selection networks over the padded rows, all lines at once (min/max, vectorised;
    :func:`dancedata.compute.jit_kernels.window_median`). Falls back to SciPy for even sizes,
    non-float data or lines shorter than ``size``.
    """
    import scipy.ndimage

    from dancedata.compute.jit_kernels import window_median

    data = np.asarray(values)
    if data.ndim != 2:
        raise ValueError(f"median_filter_axis needs a 2-d array, got shape {data.shape}")
    sizes = [1, 1]
    sizes[axis] = int(size)
    if size % 2 == 0 or size < 3 or data.shape[axis] < size or data.dtype.kind != "f":
        return scipy.ndimage.median_filter(data, size=tuple(sizes), mode="reflect")
    half = int(size) // 2
    positions = np.moveaxis(data, axis, 0)  # (positions along axis, lines)
    padded = np.pad(positions, ((half, half), (0, 0)), mode="symmetric")  # = scipy "reflect"
    out = np.empty(positions.shape, dtype=data.dtype)
    k = int(size)
    window_median(padded, _network(k), _network(k - 1, (k // 2 - 1, k // 2)), k, out)
    return np.moveaxis(out, 0, axis)


_NETWORKS: dict[tuple[int, tuple[int, ...]], np.ndarray] = {}


def _network(n: int, positions: tuple[int, ...] | None = None) -> np.ndarray:
    """:func:`dancedata.compute.jit_kernels.selection_network` of ``n`` values for ranks
    ``positions`` (default: the median), built once per process."""
    from dancedata.compute.jit_kernels import selection_network

    key = (n, positions if positions is not None else (n // 2,))
    if key not in _NETWORKS:
        _NETWORKS[key] = selection_network(*key)
    return _NETWORKS[key]


def hpss_masks(mag: np.ndarray, kernel: int) -> tuple[np.ndarray, np.ndarray]:
    """Harmonic and percussive soft masks of a magnitude spectrogram (bins, frames).

    The same numbers as ``librosa.decompose.hpss(mag, kernel_size=kernel, mask=True)`` (margin 1,
    power 2): harmonic = median over ``kernel`` frames in time, percussive = median over
    ``kernel`` bins in frequency, masks h²/(h² + p²) and p²/(h² + p²) (0.5 each where both are
    0), with the medians of :func:`median_filter_axis`.
    """
    import librosa

    harm = median_filter_axis(mag, kernel, axis=1)
    perc = median_filter_axis(mag, kernel, axis=0)
    mask_harm = librosa.util.softmask(harm, perc, power=2.0, split_zeros=True)
    mask_perc = librosa.util.softmask(perc, harm, power=2.0, split_zeros=True)
    return mask_harm, mask_perc


def percussive_mask(mag: np.ndarray, kernel: int) -> np.ndarray:
    """The percussive mask of :func:`hpss_masks` alone (the same numbers; the harmonic mask,
    which the stem masks derive as 1 − percussive, is not computed)."""
    harm = median_filter_axis(mag, kernel, axis=1)
    perc = median_filter_axis(mag, kernel, axis=0)
    return softmask(perc, harm, split_zeros=True)


def softmask(x: np.ndarray, ref: np.ndarray, split_zeros: bool) -> np.ndarray:
    """``librosa.util.softmask(x, ref, power=2, split_zeros=split_zeros)`` of non-negative
    2-d arrays, the same numbers in one compiled pass
    (:func:`dancedata.compute.jit_kernels.softmask_square`); in ``x``'s float dtype."""
    from dancedata.compute.jit_kernels import softmask_square

    x = np.ascontiguousarray(x)
    if x.dtype.kind != "f":
        x = x.astype(np.float32)
    ref = np.ascontiguousarray(ref, dtype=x.dtype)
    if x.shape != ref.shape or x.ndim != 2:
        raise ValueError(f"softmask needs two 2-d arrays of one shape, got {x.shape}, {ref.shape}")
    if np.any(x < 0) or np.any(ref < 0):
        raise ValueError("softmask inputs must be non-negative")
    return softmask_square(x, ref, bool(split_zeros), float(np.finfo(x.dtype).tiny))


# Longest clip (frames) whose whole similarity matrix is kept, float32: 4096 frames (68 s at
# 60 fps) take 64 MB; longer clips compute every block's full row of similarities instead.
_TRIANGLE_FRAMES = 4096


def repetition_background(
    mag: np.ndarray, width: int, neighbours: int = 21, block: int = 128
) -> np.ndarray:
    """Repeating background of a magnitude spectrogram (bins, frames), REPET-SIM style.

    For every frame, take the ``neighbours`` most similar other frames by cosine similarity that
    are at least ``width`` frames away (fewer when the clip is short; made odd so the median is one
    of the values) and return their per-bin median. librosa's ``nn_filter`` default would take
    k = 2·sqrt(frames) neighbours (about 80 for a 30 s song at 60 fps); 21 gives the same kind of
    background at a quarter of the cost. Computed one block of ``block`` frames at a time, with
    one similarity matrix product and a partial sort per block, so memory stays bounded
    (block × frames similarities); the medians are a compiled median network
    (:func:`dancedata.compute.jit_kernels.neighbour_median`), which picks the very values a
    sort would. When no frame is far enough away, the spectrogram is its own background.
    """
    from dancedata.compute.jit_kernels import neighbour_median, row_norms

    # (frames, bins): each neighbour is one row (no copy for a Fortran-ordered |STFT|)
    frames = np.ascontiguousarray(np.asarray(mag, dtype=np.float32).T)
    n = frames.shape[0]
    candidates = n - (2 * width - 1)
    if width < 1 or candidates < 1 or neighbours < 1:
        return np.ascontiguousarray(frames.T)
    k = min(candidates, int(neighbours))
    k -= 1 - k % 2
    norms = row_norms(frames)  # np.linalg.norm(mag, axis=0)'s bits
    unit_rows = frames / np.maximum(norms, np.finfo(np.float32).tiny)[:, None]
    out = np.empty_like(frames)
    pairs = _network(k)
    # The similarity matrix is symmetric: up to _TRIANGLE_FRAMES frames only the upper
    # triangle is computed (each block of rows against itself and the later frames, the
    # earlier columns copied from the rows above: half the products). Its entries differ
    # from a full product's by float32 rounding (BLAS does not round a·b and b·a alike);
    # no neighbour set changed on the reference tracks (tests/featurize/test_audio_reference.py).
    triangle = np.empty((n, n), dtype=np.float32) if n <= _TRIANGLE_FRAMES else None
    unit: np.ndarray | None = None  # (bins, frames), for the full products of long clips
    # One BLAS thread for the similarity products: threads add CPU time here (measured 0.34
    # against 0.10 CPU s on 30 s of audio, two cores) and gain little wall time on a busy machine.
    with one_thread("blas"):
        for start in range(0, n, block):
            stop = min(start + block, n)
            if triangle is None:
                if unit is None:
                    unit = np.ascontiguousarray(unit_rows.T)
                similarity = unit_rows[start:stop] @ unit
            else:
                rows = triangle[start:stop]
                np.matmul(unit_rows[start:stop], unit_rows[start:].T, out=rows[:, start:])
                rows[:, :start] = triangle[:start, start:stop].T
                similarity = rows.copy()
            for row in range(stop - start):  # frames closer than ``width`` are not neighbours
                frame = start + row
                similarity[row, max(0, frame - width + 1) : frame + width] = -np.inf
            nearest = np.argpartition(-similarity, k - 1, axis=1)[:, :k]
            # the k neighbours' median per bin, compiled: no (block, k, bins) copy to sort
            neighbour_median(frames, nearest, out, start, pairs)
    return out.T  # (bins, frames), Fortran-ordered like the |STFT| it came from


def repetition_foreground(
    harmonic_mag: np.ndarray, width: int, margin: float, neighbours: int = 21
) -> np.ndarray:
    """Soft mask in [0, 1] of the energy that the repeating background does not explain.

    ``harmonic_mag`` is (bins, frames); ``width`` in frames (see :func:`repetition_background`).
    The mask is fg² / (fg² + (margin·bg)²) with bg = min(mag, background), fg = mag − bg.
    """
    if not np.any(harmonic_mag > 0):
        return np.zeros_like(harmonic_mag)
    background = np.minimum(harmonic_mag, repetition_background(harmonic_mag, width, neighbours))
    foreground = harmonic_mag - background
    return softmask(foreground, margin * background, split_zeros=False)


def stem_masks(
    mag: np.ndarray,
    sr: float,
    n_fft: int,
    hop_length: int,
    hpss_kernel: int,
    bass_cutoff_hz: float,
    vocal_high_hz: float,
    crossover_order: int,
    repeat_seconds: float,
    repeat_neighbours: int,
    vocal_margin: float,
) -> dict[str, np.ndarray]:
    """Four soft masks (bins, frames) for a magnitude spectrogram; they sum to 1 in every bin.

    Pure: ``mag`` is |STFT| of the mix with ``n_fft`` and ``hop_length`` at ``sr`` Hz.
    """
    import librosa

    # float32 throughout (the masks, and so the masked spectra and their inverse STFTs, which
    # float64 masks would promote to complex128): half the memory traffic and FFT work, and
    # the stems change only by float32 rounding.
    percussive = percussive_mask(np.asarray(mag, dtype=np.float32), hpss_kernel)
    # librosa leaves bins where both median filters are 0 at (0, 0); give them to the harmonic
    # side so that the masks are an exact partition of unity.
    harmonic = np.float32(1.0) - percussive

    freqs = librosa.fft_frequencies(sr=sr, n_fft=n_fft)
    low64 = lowpass_weight(freqs, bass_cutoff_hz, crossover_order)
    band = ((1.0 - low64) * lowpass_weight(freqs, vocal_high_hz, crossover_order)).astype(
        np.float32
    )
    low = low64.astype(np.float32)

    width = max(1, int(round(repeat_seconds * sr / hop_length)))
    novel = repetition_foreground(mag * harmonic, width, vocal_margin, repeat_neighbours)

    bass = harmonic * low[:, None]
    vocals = harmonic * band[:, None] * novel
    other = harmonic - bass - vocals
    return {
        "drums": percussive,
        "bass": bass,
        "vocals": vocals,
        "other": np.clip(other, np.float32(0), None),
    }


def separate(
    y: np.ndarray, sr: float, *, stft: np.ndarray | None = None, **options: Any
) -> dict[str, np.ndarray]:
    """Four approximate stems of ``y`` (mono or (channels, samples)) at ``sr`` Hz.

    Stems are mono float32 with ``y``'s length; they sum to the (mono) input. ``options``
    override :data:`DEFAULTS`. ``stft``, when given, is ``librosa.stft`` of the mono mix with
    this ``n_fft`` and ``hop_length`` (Hann, centred), computed once per track and shared with
    the FACT features; it must have the shape that STFT has.
    """
    import librosa

    params = {**DEFAULTS, **options}
    mono = to_mono(y)
    n_fft, hop = int(params["n_fft"]), int(params["hop_length"])
    if stft is None:
        spec = librosa.stft(mono, n_fft=n_fft, hop_length=hop)
    else:
        expected = (1 + n_fft // 2, 1 + mono.shape[-1] // hop)
        if stft.shape != expected:
            raise ValueError(f"shared STFT has shape {stft.shape}, expected {expected}")
        spec = stft
    masks = stem_masks(np.abs(spec), sr, **params)
    inverse = InverseSTFT(n_fft, hop, mono.shape[-1], spec.shape[-1])
    return {name: inverse(spec, masks[name]).astype(np.float32) for name in STEM_NAMES}


class InverseSTFT:
    """``librosa.istft(S, n_fft=n_fft, hop_length=hop, length=length)`` (Hann, centred) of
    spectra of ``frames`` frames, with the same bits, for several spectra of one shape.

    For complex64 spectra the window's sum of squares is computed once, the inverse FFTs run
    256 frames at a time (librosa: ~31, its 256 kB blocks) and the windowing and overlap-add
    are one compiled pass (:func:`dancedata.compute.jit_kernels.overlap_add`) instead of a
    float64 product of every block: 0.021 -> 0.011 CPU s per 30 s stem (measured). complex128
    spectra go to librosa.istft.
    """

    _BLOCK = 256

    def __init__(self, n_fft: int, hop: int, length: int, frames: int) -> None:
        import librosa

        self.n_fft, self.hop, self.length = int(n_fft), int(hop), int(length)
        half = self.n_fft // 2
        self.frames = min(int(frames), int(np.ceil((self.length + 2 * half) / self.hop)))
        window = librosa.filters.get_window("hann", self.n_fft, fftbins=True)
        self.window = np.ascontiguousarray(librosa.util.pad_center(window, size=self.n_fft))
        norm = librosa.filters.window_sumsquare(
            window="hann",
            n_frames=self.frames,
            win_length=self.n_fft,
            n_fft=self.n_fft,
            hop_length=self.hop,
            dtype=np.float32,
        )
        self.norm = np.ascontiguousarray(librosa.util.fix_length(norm[half:], size=self.length))

    def __call__(self, spectrum: np.ndarray, mask: np.ndarray | None = None) -> np.ndarray:
        """The float32 signal of one complex64 spectrum (bins, frames), times ``mask`` (same
        shape) when given: the product is taken block by block in the frames-first order the
        inverse FFTs read (the same products as ``spectrum * mask``, without a (bins, frames)
        temporary in the other memory order)."""
        import librosa

        from dancedata.compute.jit_kernels import divide_where_above, overlap_add

        spec = np.asarray(spectrum)
        if spec.ndim != 2 or spec.shape[0] != 1 + self.n_fft // 2 or spec.shape[1] < self.frames:
            raise ValueError(
                f"spectrum of shape {spec.shape} does not fit a {self.n_fft}-point STFT of "
                f"{self.frames} frames"
            )
        if mask is not None and mask.shape != spec.shape:
            raise ValueError(f"mask of shape {mask.shape} does not fit spectrum {spec.shape}")
        if spec.dtype != np.complex64 or (mask is not None and mask.dtype != np.float32):
            if mask is not None:  # librosa's own path for double precision
                spec = spec * mask
            return librosa.istft(spec, hop_length=self.hop, n_fft=self.n_fft, length=self.length)
        irfft = librosa.get_fftlib().irfft
        y = np.zeros(self.length, dtype=np.float32)
        rows = spec.T  # (frames, bins): each frame's inverse FFT is one contiguous row
        mask_rows = None if mask is None else mask.T
        for first in range(0, self.frames, self._BLOCK):
            stop = min(first + self._BLOCK, self.frames)
            part = rows[first:stop]
            if mask_rows is not None:
                part = part * mask_rows[first:stop]
            block = np.ascontiguousarray(irfft(part, n=self.n_fft, axis=-1))
            overlap_add(y, block, self.window, first, self.hop, self.n_fft // 2)
        divide_where_above(y, self.norm, float(np.finfo(np.float32).tiny))
        return y
