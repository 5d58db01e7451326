"""Compiled loops of the audio features, each a plain function of arrays (numba, ``cache=True``).

Every kernel is compiled on its first call and the machine code is kept in numba's on-disk cache
(next to this file, or in numba's per-user cache folder when that is read-only), so compilation
is paid once per machine and installed version, not once per process or worker. Import this
module only where a kernel is called: it imports numba.

Kernels compute exactly what the numpy code they replace computed (a selection returns one of
its inputs; the loops add in the same order), so results are identical, not merely close.
"""

from __future__ import annotations

import numba
import numpy as np


def median_network(k: int) -> np.ndarray:
    """Comparators (c, 2) int64 of a network that puts the median of ``k`` values at position
    ``k // 2`` (:func:`selection_network`; 152 comparators for k = 31, 91 for k = 21)."""
    return selection_network(k, (k // 2,))


def selection_network(n: int, positions: tuple[int, ...]) -> np.ndarray:
    """Comparators (c, 2) int64 that put the values of ranks ``positions`` among ``n`` values
    at those positions: Batcher's odd-even merge sort for the next power of two, without the
    comparators that touch positions ≥ ``n`` (those would hold +inf, which no comparator moves)
    and without those the wanted positions do not depend on. Each comparator (a, b), a < b,
    puts the smaller value at a and the larger at b; min and max select inputs, so each wanted
    position holds the very value a sort would put there."""
    if n < 1 or not positions or min(positions) < 0 or max(positions) >= n:
        raise ValueError(f"cannot select ranks {positions} of {n} values")
    size = 1
    while size < n:
        size *= 2
    pairs = []
    p = 1
    while p < size:
        step = p
        while step >= 1:
            for j in range(step % p, size - step, 2 * step):
                for i in range(min(step, size - j - step)):
                    if (i + j) // (2 * p) == (i + j + step) // (2 * p) and i + j + step < n:
                        pairs.append((i + j, i + j + step))
            step //= 2
        p *= 2
    needed, kept = set(positions), []
    for a, b in reversed(pairs):
        if a in needed or b in needed:
            kept.append((a, b))
            needed.update((a, b))
    return np.array(kept[::-1], dtype=np.int64).reshape(-1, 2)


@numba.njit(cache=True, nogil=True)
def _apply_network(buf: np.ndarray, pairs: np.ndarray, width: int, scratch: np.ndarray) -> None:
    """The comparators ``pairs`` on the rows of ``buf``, column by column of ``buf[:, :width]``
    (vectorised across the columns: min and max, no branch). ``scratch`` holds ≥ ``width``
    values of ``buf``'s dtype.

    The selects are those of Python's ``min`` and ``max`` (y if y < x else x; y if y > x else
    x), so NaN and signed zeros land where the builtins put them. The minima go to ``scratch``
    first and are copied back after: written straight into a row of ``buf`` that the same loop
    also reads through another row, LLVM cannot prove the rows apart and leaves the loop scalar
    on AVX2 machines (3.8x slower measured on a Zen 3 core)."""
    for c in range(pairs.shape[0]):
        low = buf[pairs[c, 0]]
        high = buf[pairs[c, 1]]
        for j in range(width):
            x = low[j]
            y = high[j]
            scratch[j] = y if y < x else x
            high[j] = y if y > x else x
        for j in range(width):
            low[j] = scratch[j]


_CHUNK = 256  # columns per pass: k rows of 256 float32 stay in the L1 cache


@numba.njit(cache=True, nogil=True)
def window_median(
    padded: np.ndarray, pairs: np.ndarray, shared: np.ndarray, k: int, out: np.ndarray
) -> None:
    """``out[i, c]`` = median of ``padded[i : i + k, c]``: a running median down the rows, all
    columns at once (k odd, k = 2h + 1 ≥ 3).

    Two neighbouring windows share 2h rows; with those rows' values of ranks h − 1 and h
    (``shared`` = :func:`selection_network` of (2h, (h − 1, h))), each window's median is its
    own extra value clamped between them, so one network serves two outputs. A last odd row
    takes the full median network ``pairs`` (:func:`median_network` of k). Every output is one
    of its window's values, the one a sort would put in the middle.
    """
    rows, cols = out.shape
    buf = np.empty((k, _CHUNK), dtype=padded.dtype)
    scratch = np.empty(_CHUNK, dtype=padded.dtype)
    half = k // 2
    for c0 in range(0, cols, _CHUNK):
        width = min(_CHUNK, cols - c0)
        for i in range(0, rows - 1, 2):
            for r in range(k - 1):
                buf[r, :width] = padded[i + 1 + r, c0 : c0 + width]
            _apply_network(buf, shared, width, scratch)
            low = buf[half - 1]
            high = buf[half]
            first = padded[i, c0 : c0 + width]
            second = padded[i + k, c0 : c0 + width]
            for j in range(width):
                out[i, c0 + j] = min(max(first[j], low[j]), high[j])
                out[i + 1, c0 + j] = min(max(second[j], low[j]), high[j])
        if rows % 2:
            i = rows - 1
            for r in range(k):
                buf[r, :width] = padded[i + r, c0 : c0 + width]
            _apply_network(buf, pairs, width, scratch)
            out[i, c0 : c0 + width] = buf[half, :width]


@numba.njit(cache=True, nogil=True)
def neighbour_median(
    frames: np.ndarray, nearest: np.ndarray, out: np.ndarray, start: int, pairs: np.ndarray
) -> None:
    """``out[start + j, b]`` = median over i of ``frames[nearest[j, i], b]``.

    ``frames`` is (frames, bins), ``nearest`` (rows, k) frame indices with k odd, ``out``
    (frames, bins), ``pairs`` :func:`median_network` of k. The k gathered rows go through the
    median network, all bins at once: the very value ``np.partition(..., k // 2)`` picks.
    """
    rows, k = nearest.shape
    bins = frames.shape[1]
    mid = k // 2
    buf = np.empty((k, _CHUNK), dtype=frames.dtype)
    scratch = np.empty(_CHUNK, dtype=frames.dtype)
    for j in range(rows):
        target = out[start + j]
        for c0 in range(0, bins, _CHUNK):
            width = min(_CHUNK, bins - c0)
            for r in range(k):
                buf[r, :width] = frames[nearest[j, r], c0 : c0 + width]
            _apply_network(buf, pairs, width, scratch)
            target[c0 : c0 + width] = buf[mid, :width]


@numba.njit(cache=True, nogil=True)
def overlap_add(
    y: np.ndarray, frames: np.ndarray, window: np.ndarray, first: int, hop: int, offset: int
) -> None:
    """Windowed overlap-add of inverse-FFT frames into ``y``, as ``librosa.istft`` adds them.

    ``frames`` (count, n_fft) float32 are frames ``first``, ``first + 1``, ... of the STFT;
    frame f starts at sample f·hop − ``offset`` of ``y`` (``offset`` = n_fft // 2 for a centred
    STFT), samples outside ``y`` are dropped. Each sample takes window[i]·frame[i] in float64
    (librosa multiplies the float32 frames by its float64 window) and is added to ``y``'s
    float32 value in float64, rounded back to float32, frame after frame: librosa's operations
    in librosa's order, so the same bits.
    """
    count, n_fft = frames.shape
    length = y.shape[0]
    for b in range(count):
        start = (first + b) * hop - offset
        lo = max(0, -start)
        hi = min(n_fft, length - start)
        for i in range(lo, hi):
            product = window[i] * np.float64(frames[b, i])
            y[start + i] = np.float32(np.float64(y[start + i]) + product)


@numba.njit(cache=True, nogil=True)
def divide_where_above(y: np.ndarray, norm: np.ndarray, tiny: float) -> None:
    """``y[i] /= norm[i]`` where ``norm[i] > tiny``, in ``y``'s dtype (librosa.istft's last
    step, dividing by the window's sum of squares)."""
    for i in range(y.shape[0]):
        if norm[i] > tiny:
            y[i] = y[i] / norm[i]


@numba.njit(cache=True, nogil=True, error_model="numpy")
def kl_ratio(v: np.ndarray, approx: np.ndarray, floor: float) -> None:
    """``approx[i] = v[i] / max(approx[i], floor)`` in place, 1-D arrays of one dtype: NMFD's
    V / Λ in one pass instead of np.maximum then np.divide (same operations in the same dtype,
    so the same values; ``error_model="numpy"`` drops the zero check so the loop vectorises)."""
    tiny = approx.dtype.type(floor)
    for i in range(approx.size):
        x = approx[i]
        approx[i] = v[i] / (x if x > tiny else tiny)


@numba.njit(cache=True, nogil=True)
def row_norms(rows: np.ndarray) -> np.ndarray:
    """Euclidean norm of each row of a C-contiguous (n, k) array, in its dtype: the squares
    added first to last, as ``np.linalg.norm(rows.T_as_C_order, axis=0)`` adds them (numpy
    reduces a C-ordered axis 0 row after row), so the same bits without the transposed copy."""
    out = np.empty(rows.shape[0], dtype=rows.dtype)
    for i in range(rows.shape[0]):
        row = rows[i]
        total = row[0] * row[0]
        for j in range(1, row.shape[0]):
            total += row[j] * row[j]
        out[i] = np.sqrt(total)
    return out


# -- beat tracking (the dynamic program of Ellis 2007, as librosa.beat.beat_track runs it) -----
# librosa 0.11 compiles one of these loops at import without caching it (about 1-3 s per
# process); these are the same loops, with the same arithmetic in the same order (float64, as
# librosa's float64 kernels run for a float32 envelope with a float64 tempo), compiled once.


@numba.njit(cache=True, nogil=True)
def beat_local_score(onsets: np.ndarray, frames_per_beat: float) -> np.ndarray:
    """The onsets smoothed by a Gaussian of ±``frames_per_beat`` frames (σ = 1/32 of it), as a
    same-size convolution whose last tap (at offset + K // 2) is left out, as librosa's is."""
    n = onsets.shape[0]
    window = np.exp(
        -0.5 * (np.arange(-frames_per_beat, frames_per_beat + 1) * 32.0 / frames_per_beat) ** 2
    )
    taps = window.shape[0]
    half = taps // 2
    score = np.empty(n, dtype=np.float64)
    for i in range(n):
        score[i] = 0.0
        for k in range(max(0, i + half - n + 1), min(i + half, taps)):
            score[i] += window[k] * onsets[i + half - k]
    return score


@numba.njit(cache=True, nogil=True)
def beat_track_dp(
    localscore: np.ndarray, frames_per_beat: float, tightness: float
) -> tuple[np.ndarray, np.ndarray]:
    """(backlink int32, cumulative score float64): each frame's best predecessor beat between
    2 and 1/2 beat periods back, scored by the log-period deviation squared × ``tightness``."""
    n = localscore.shape[0]
    backlink = np.empty(n, dtype=np.int32)
    cumscore = np.empty(n, dtype=np.float64)
    score_thresh = 0.01 * localscore.max()
    first_beat = True
    backlink[0] = -1
    cumscore[0] = localscore[0]
    log_period = np.log(frames_per_beat)
    nearest = int(np.round(frames_per_beat / 2))
    farthest = int(2 * frames_per_beat)
    for i in range(n):
        score_i = localscore[i]
        best_score = -np.inf
        beat_location = -1
        for loc in range(i - nearest, i - farthest - 1, -1):
            if loc < 0:
                break
            score = cumscore[loc] - tightness * (np.log(i - loc) - log_period) ** 2
            if score > best_score:
                best_score = score
                beat_location = loc
        if beat_location >= 0:
            cumscore[i] = score_i + best_score
        else:
            cumscore[i] = score_i
        if first_beat and score_i < score_thresh:
            backlink[i] = -1
        else:
            backlink[i] = beat_location
            first_beat = False
    return backlink, cumscore


@numba.njit(cache=True, nogil=True)
def beat_backtrack_and_trim(
    localscore: np.ndarray, backlink: np.ndarray, tail: int, trim: bool
) -> np.ndarray:
    """Beats (bool per frame) from following the backlinks from ``tail``, without the leading
    and trailing frames whose local score is at most half the RMS of the beats' local score
    smoothed by a 5-point Hann window (only those scoring 0 when not ``trim``)."""
    n = localscore.shape[0]
    beats = np.zeros(n, dtype=np.bool_)
    frame = tail
    while frame >= 0:
        beats[frame] = True
        frame = backlink[frame]
    window = np.hanning(5)
    half = window.shape[0] // 2
    smooth = np.convolve(localscore[beats], window)[half : n + half]
    threshold = 0.5 * ((smooth**2).mean() ** 0.5) if trim else 0.0
    frame = 0
    while frame < n and localscore[frame] <= threshold:
        beats[frame] = False
        frame += 1
    frame = n - 1
    while frame >= 0 and localscore[frame] <= threshold:
        beats[frame] = False
        frame -= 1
    return beats


@numba.njit(cache=True, nogil=True)
def softmask_square(x: np.ndarray, ref: np.ndarray, split_zeros: bool, tiny: float) -> np.ndarray:
    """``librosa.util.softmask(x, ref, power=2, split_zeros=split_zeros)`` of two 2-d arrays of
    one float dtype, in one pass: with z = max(x, ref), (x/z)² / ((x/z)² + (ref/z)²), and 0.5
    (``split_zeros``) or 0 where z < ``tiny`` (the dtype's smallest normal number). The same
    operations in the same order and dtype as librosa's, without its six temporaries."""
    rows, cols = x.shape
    out = np.empty_like(x)
    zero = 0.5 if split_zeros else 0.0
    for i in range(rows):
        for j in range(cols):
            a = x[i, j]
            b = ref[i, j]
            z = max(a, b)
            if z < tiny:
                out[i, j] = zero
            else:
                a = a / z
                b = b / z
                a = a * a
                out[i, j] = a / (a + b * b)
    return out
