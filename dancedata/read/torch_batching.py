"""PyTorch batching for the window datasets of :mod:`dancedata.read.torch_data` (needs torch).

    from torch.utils.data import DataLoader
    from dancedata.read.torch_data import MeasureDataset
    from dancedata.read.torch_batching import LengthBucketSampler, pad_collate

    ds = MeasureDataset("data/stores/aist-demo", split="train")
    loader = DataLoader(ds, batch_sampler=LengthBucketSampler(ds.lengths, 8, seed=0),
                        collate_fn=pad_collate, num_workers=2)
    for batch in loader:
        batch["motion"]   # (B, T, 225) float32, zero after each item's end
        batch["mask"]     # (B, T) bool, True on real frames
        batch["length"]   # (B,) int64 (also as batch["lengths"])

Padding, masks and seeded orders follow :mod:`dancedata.read.batching` (numpy, no torch).
"""

from __future__ import annotations

from collections.abc import Iterator, Sequence
from typing import Any

import numpy as np
import torch
from torch.utils.data import BatchSampler, DataLoader, Sampler, get_worker_info

from dancedata.read.batching import bucket_batches, epoch_permutation, lengths_mask, padded_length

TIME_KEYS = ("motion", "audio")


class PadCollate:
    """``collate_fn`` padding ``motion`` / ``audio`` at the end of time to the batch's longest
    item (rounded up to ``multiple_of``) with ``pad_value``; adds ``mask`` (B, T) bool and
    ``lengths`` (B,) int64. Other tensors are stacked, numbers become tensors, strings lists.
    Items with their own ``mask`` and ``length`` (fixed-length windows) keep them."""

    def __init__(self, multiple_of: int = 1, pad_value: float = 0.0) -> None:
        if multiple_of < 1:
            raise ValueError(f"multiple_of must be ≥ 1 (got {multiple_of})")
        self.multiple_of = multiple_of
        self.pad_value = pad_value

    def __call__(self, items: Sequence[dict[str, Any]]) -> dict[str, Any]:
        time_keys = [k for k in TIME_KEYS if k in items[0]]
        if not time_keys:
            raise ValueError("pad_collate needs items with 'motion' or 'audio'")
        frames = [int(item[time_keys[0]].shape[0]) for item in items]
        lengths = [int(item.get("length", n)) for item, n in zip(items, frames, strict=True)]
        total = padded_length(frames, self.multiple_of)
        out: dict[str, Any] = {}
        for key in items[0]:
            values = [item[key] for item in items]
            if key in TIME_KEYS:
                out[key] = _pad(values, lengths, total, self.pad_value)
            elif key in ("mask", "length"):
                continue
            elif isinstance(values[0], str):
                out[key] = list(values)
            elif isinstance(values[0], torch.Tensor | np.ndarray):
                out[key] = torch.stack([torch.as_tensor(v) for v in values])
            else:
                out[key] = torch.tensor(values)
        # "length" as the DataLoader's own batches (torch_data) name it; "lengths" kept as well
        out["length"] = out["lengths"] = torch.tensor(lengths, dtype=torch.int64)
        out["mask"] = torch.from_numpy(lengths_mask(lengths, total))
        return out


def _pad(values: list[Any], lengths: list[int], total: int, pad_value: float) -> torch.Tensor:
    """(B, total, ...) of ``values`` with ``pad_value`` after each item's ``lengths[b]`` real
    frames (items may arrive already padded, e.g. by a dataset's ``__getitems__``)."""
    first = torch.as_tensor(values[0])
    out = torch.full((len(values), total, *first.shape[1:]), pad_value, dtype=first.dtype)
    for i, (v, n) in enumerate(zip(values, lengths, strict=True)):
        v = torch.as_tensor(v)
        out[i, : v.shape[0]] = v
        if pad_value != 0.0 and n < v.shape[0]:
            out[i, n:] = pad_value
    return out


pad_collate = PadCollate()
"""The default :class:`PadCollate` (no rounding, zeros)."""


class SeededShuffleSampler(Sampler[int]):
    """A permutation of ``range(n)`` per epoch from ``default_rng([seed, epoch])``: same seed,
    same order, whatever torch's RNG state or the number of workers. The epoch advances by one
    after each complete pass, or is set with :meth:`set_epoch`."""

    def __init__(self, n: int, seed: int = 0, epoch: int = 0) -> None:
        self.n, self.seed, self.epoch = int(n), int(seed), int(epoch)

    def set_epoch(self, epoch: int) -> None:
        self.epoch = int(epoch)

    def __len__(self) -> int:
        return self.n

    def __iter__(self) -> Iterator[int]:
        # A generator: the epoch advances only once a pass has been read to its end (DataLoader
        # may call iter() on a sampler more than once before reading it).
        yield from epoch_permutation(self.n, self.seed, self.epoch).tolist()
        self.epoch += 1


class LengthBucketSampler(Sampler[list[int]]):
    """A ``batch_sampler`` of batches with similar window lengths
    (:func:`dancedata.read.batching.bucket_batches`): every index once per epoch, max − min length
    within a batch ≤ ``max_spread`` frames when given, batch order shuffled from
    ``default_rng([seed, epoch])``. The epoch advances after each full pass (or set_epoch)."""

    def __init__(
        self,
        lengths: Sequence[int] | np.ndarray,
        batch_size: int,
        *,
        seed: int = 0,
        max_spread: int | None = None,
        shuffle: bool = True,
        drop_last: bool = False,
        epoch: int = 0,
    ) -> None:
        self.lengths = np.asarray(lengths, dtype=np.int64)
        self.batch_size, self.seed, self.max_spread = batch_size, int(seed), max_spread
        self.shuffle, self.drop_last, self.epoch = shuffle, drop_last, int(epoch)

    def set_epoch(self, epoch: int) -> None:
        self.epoch = int(epoch)

    def batches(self, epoch: int | None = None) -> list[np.ndarray]:
        """The batches of ``epoch`` (default: the current one) without advancing."""
        return bucket_batches(
            self.lengths,
            self.batch_size,
            seed=self.seed,
            epoch=self.epoch if epoch is None else epoch,
            max_spread=self.max_spread,
            shuffle=self.shuffle,
            drop_last=self.drop_last,
        )

    def __len__(self) -> int:
        return len(self.batches())

    def __iter__(self) -> Iterator[list[int]]:
        for batch in self.batches():  # the epoch advances once a pass is read to its end
            yield batch.tolist()
        self.epoch += 1


class EpochBatches(Sampler[tuple[int, list[int]]]):
    """A batch sampler whose batches travel with their epoch: yields ``(epoch, indices)``,
    the epoch read from the wrapped sampler (``SeededShuffleSampler``,
    ``LengthBucketSampler``) when a pass starts. So per-epoch augmentation draws follow the
    epoch in persistent data-loader workers too, which never see the training process's
    ``set_epoch``. ``set_epoch`` is passed on to the wrapped sampler."""

    def __init__(self, batches: Any) -> None:
        self.batches = batches
        self._epoch_of = getattr(batches, "sampler", batches)

    def set_epoch(self, epoch: int) -> None:
        self._epoch_of.set_epoch(epoch)

    def __len__(self) -> int:
        return len(self.batches)

    def __iter__(self) -> Iterator[tuple[int, list[int]]]:
        epoch = int(getattr(self._epoch_of, "epoch", 0))
        for batch in self.batches:
            yield epoch, list(batch)


class BatchReads:
    """A dataset whose items are whole batches: ``reads[indices]`` is ``dataset.batch(indices)``
    (padded, one copy per window), ``reads[(epoch, indices)]`` the batch of that epoch (see
    :class:`EpochBatches`). Used with ``DataLoader(reads, sampler=<batch sampler>,
    batch_size=None)``, so workers build batches without a per-item step; in a worker a
    dataset's ``batch_parcel`` (one shared-memory buffer per batch) is used when it has one."""

    def __init__(self, dataset: Any, multiple_of: int = 1) -> None:
        self.dataset, self.multiple_of = dataset, multiple_of

    def __len__(self) -> int:
        return len(self.dataset)

    def __getitem__(self, indices: Any) -> Any:
        epoch = None
        if isinstance(indices, tuple) and len(indices) == 2 and isinstance(indices[1], list):
            epoch, indices = indices
        extra = {} if epoch is None else {"epoch": epoch}
        if get_worker_info() is not None and getattr(self.dataset, "batch_parcel", None):
            return self.dataset.batch_parcel(list(indices), self.multiple_of, **extra)  # as
        return self.dataset.batch(list(indices), self.multiple_of, **extra)  # the same dict


def _as_is(batch: Any) -> Any:
    return batch


def training_loader(
    dataset: Any,
    batch_size: int,
    *,
    seed: int = 0,
    bucket: bool = False,
    max_spread: int | None = None,
    num_workers: int = 0,
    drop_last: bool = False,
    collate_fn: Any = None,
    **loader_kwargs: Any,
) -> DataLoader:
    """A DataLoader over a window dataset with padding collate and a seeded order: a plain
    seeded shuffle, or length buckets with ``bucket=True``. Batches are as
    :func:`pad_collate` makes them; without a ``collate_fn`` they are read whole through
    ``dataset.batch`` (:class:`BatchReads`) when the dataset has it. Extra keywords go to
    DataLoader (e.g. ``pin_memory=True``); workers persist between epochs by default. Read
    through ``dataset.batch``, each batch carries its epoch (:class:`EpochBatches`), so a
    dataset's augmentations draw per seed, epoch and index whatever the workers."""
    if num_workers > 0:
        loader_kwargs.setdefault("persistent_workers", True)
    if bucket:
        batches: Sampler = LengthBucketSampler(
            dataset.lengths, batch_size, seed=seed, max_spread=max_spread, drop_last=drop_last
        )
    else:
        batches = BatchSampler(SeededShuffleSampler(len(dataset), seed), batch_size, drop_last)
    if collate_fn is None and hasattr(dataset, "batch"):
        return DataLoader(
            BatchReads(dataset),
            sampler=EpochBatches(batches),
            batch_size=None,
            collate_fn=_as_is,
            num_workers=num_workers,
            **loader_kwargs,
        )
    return DataLoader(
        dataset,
        batch_sampler=batches,
        collate_fn=pad_collate if collate_fn is None else collate_fn,
        num_workers=num_workers,
        **loader_kwargs,
    )
