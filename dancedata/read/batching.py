"""Batching without torch: padding with masks, seeded shuffles, and length buckets.

Conventions (the torch wrappers in :mod:`dancedata.read.torch_batching` follow them):

* padding is at the end of the time axis (axis 0 of each item) with ``pad_value`` (0);
  ``mask[b, t]`` is True where frame ``t`` of item ``b`` is real, ``lengths[b]`` counts them;
* every random order comes from ``numpy.random.default_rng([seed, epoch])`` (PCG64): the same
  seed and epoch give the same order on any machine and numpy ≥ 1.17, independent of torch's
  RNG and of the number of data-loader workers.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from dancedata.errors import InputError


def padded_length(lengths: Sequence[int], multiple_of: int = 1) -> int:
    """The longest length, rounded up to a multiple of ``multiple_of``."""
    longest = max((int(n) for n in lengths), default=0)
    return -(-longest // multiple_of) * multiple_of


def pad_stack(arrays: Sequence[np.ndarray], total: int, pad_value: float = 0.0) -> np.ndarray:
    """Stack (L_i, ...) arrays into (B, total, ...), padding each at the end."""
    first = arrays[0]
    out = np.full((len(arrays), total) + first.shape[1:], pad_value, dtype=first.dtype)
    for i, a in enumerate(arrays):
        out[i, : a.shape[0]] = a
    return out


def lengths_mask(lengths: Sequence[int], total: int) -> np.ndarray:
    """(B, total) bool: True at the first ``lengths[b]`` frames of row ``b``."""
    return np.arange(total)[None, :] < np.asarray(lengths, dtype=np.int64)[:, None]


def _rng(seed: int, epoch: int) -> np.random.Generator:
    if seed < 0 or epoch < 0:
        raise InputError(f"seed and epoch must be ≥ 0 (got {seed}, {epoch})")
    return np.random.default_rng([int(seed), int(epoch)])


def epoch_permutation(n: int, seed: int, epoch: int = 0) -> np.ndarray:
    """(n,) int64 permutation of ``range(n)`` for ``epoch`` of a run seeded ``seed``."""
    return _rng(seed, epoch).permutation(n).astype(np.int64)


def bucket_batches(
    lengths: Sequence[int] | np.ndarray,
    batch_size: int,
    *,
    seed: int = 0,
    epoch: int = 0,
    max_spread: int | None = None,
    shuffle: bool = True,
    drop_last: bool = False,
) -> list[np.ndarray]:
    """Batches of indices with similar lengths, so that padding wastes little.

    Indices are sorted by length (ties in a random order when ``shuffle``), cut into runs of
    ``batch_size``, and a run is also cut where its longest and shortest lengths would differ by
    more than ``max_spread`` frames (when given); the batch order is then shuffled. Every index
    appears exactly once per epoch (unless ``drop_last`` drops the batches shorter than
    ``batch_size``); within a batch, max − min length ≤ ``max_spread``."""
    if batch_size < 1:
        raise InputError(f"batch_size must be ≥ 1 (got {batch_size})")
    if max_spread is not None and max_spread < 0:
        raise InputError(f"max_spread must be ≥ 0 frames (got {max_spread})")
    lengths = np.asarray(lengths, dtype=np.int64)
    rng = _rng(seed, epoch)
    ties = rng.random(len(lengths)) if shuffle else np.arange(len(lengths))
    order = np.lexsort((ties, lengths))
    batches: list[np.ndarray] = []
    begin = 0
    for i in range(1, len(order) + 1):
        full = i - begin == batch_size
        too_wide = (
            max_spread is not None
            and i < len(order)
            and lengths[order[i]] - lengths[order[begin]] > max_spread
        )
        if i == len(order) or full or too_wide:
            batches.append(order[begin:i])
            begin = i
    if drop_last:
        batches = [b for b in batches if len(b) == batch_size]
    if shuffle:
        batches = [batches[j] for j in rng.permutation(len(batches))]
    return batches
