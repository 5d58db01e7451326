"""PyTorch access to the windows of a store (torch is optional and imported on use; install
it with the torch extra, ``pip install 'dancedata[learned]'``).

    from torch.utils.data import DataLoader
    from dancedata.read.torch_data import MeasureDataset, SecondsDataset
    ds = MeasureDataset("data/stores/aist-demo", split="train")
    item = ds[0]   # {"motion": (T, 225) tensor, "audio": (T, 35) tensor, "genre": (G,), ...}
    for batch in DataLoader(ds, batch_size=8, shuffle=True, num_workers=2):
        batch["motion"], batch["mask"], batch["length"]   # (B, T, 225), (B, T) bool, (B,)

The default views (columns in order, per frame):

* ``motion`` = ``fact_motion_225``: columns 0–5 zeros (FACT's released data has them), 6–8
  root translation (x, y, z, metres), 9–224 the 24 SMPL joints' local rotation matrices, 9
  row-major values each (joint ``j`` at columns ``9 + 9j … 17 + 9j``) in SMPL order: root,
  lhip, rhip, belly, lknee, rknee, spine, lankle, rankle, chest, ltoes, rtoes, neck,
  linshoulder, rinshoulder, head, lshoulder, rshoulder, lelbow, relbow, lwrist, rwrist, lhand,
  rhand (:data:`dancedata.compute.motion_features.SMPL_JOINT_NAMES`).
* ``audio`` = ``fact_audio_35``: column 0 onset strength, 1–20 MFCC, 21–32 chroma CENS (C to
  B), 33 onset peaks (0/1), 34 beats (0/1), one row per motion frame.

Measures differ in length when tempi differ (and by a frame at one tempo). Batches the
DataLoader builds (``batch_size=...``) are read through :meth:`_WindowDataset.__getitems__`,
which pads the windows of a batch to its longest with zeros and adds ``mask`` (T,) bool and
``length`` to each item, so torch's default collate stacks them (without it, workers died in
that collate with "Trying to resize storage that is not resizable"). For less padding use
:func:`dancedata.read.torch_batching.training_loader` (seeded, ``bucket=True`` for length buckets)
or :func:`~dancedata.read.torch_batching.pad_collate` with
:class:`~dancedata.read.torch_batching.LengthBucketSampler`; or make every item ``window_frames``
long with ``fit="resample"|"crop"|"pad"`` (:mod:`dancedata.read.window_fit`). ``n_measures`` /
``hop_measures`` make windows of several measures; :class:`SecondsDataset` makes sliding
windows of ``seconds`` every ``hop_seconds`` (:mod:`dancedata.read.window_spans`).

Any stored arrays, not only the paper views: ``motion=`` / ``audio=`` take a view name, an array
path or a list of them, side by side in the item (``motion=["motion/quat", "motion/trans"]``,
``audio="audio/stft_frames"``; ``dataset.columns`` says which columns hold which array). A paper
view that does not fit the store (``fact_motion_225`` on a 31-joint BVH rig) is refused with the
reason. :class:`BeatDataset` and :class:`PhraseDataset` cut windows per beat span and per phrase
(the ``beats`` / ``phrases`` tables of ``dancedata segment --tables measures,beats,phrases``).
``normalize=True`` (or a list of array paths) applies the version's normalisation table
(``dancedata stats``) and ``dataset.denormalize(x)`` undoes it; ``augment=("mirror", "yaw")``
mirrors and turns items, deterministically per ``seed``, epoch (``set_epoch``) and index.

Datasets pickle small and open the store lazily in each data-loader worker (local folders and
``s3://`` stores alike), so ``num_workers > 0`` works with fork and spawn.
"""

from __future__ import annotations

from collections.abc import Iterator, Sequence
from pathlib import Path
from typing import Any

import numpy as np

from dancedata.read.loader import DanceStore
from dancedata.read.views.layouts import ViewSpec
from dancedata.read.views.measures import MeasureWindow
from dancedata.read.window_dataset import Augmentation, WindowSource, open_window_source


def _torch() -> Any:
    try:
        import torch
    except ImportError:
        raise ImportError(
            "dancedata.read.torch_data needs PyTorch: pip install 'dancedata[learned]' (the torch "
            "extra; 'dancedata[stems]' brings it too)"
        ) from None
    return torch


class _SharedBuffer:
    """An allocator for :meth:`WindowSource.batch`: every array in one new shared-memory
    float32 buffer (a new segment reads as zeros: POSIX ``ftruncate`` fills with zeros)."""

    def __init__(self) -> None:
        self.flat: Any = None
        self.shapes: dict[str, tuple[int, ...]] = {}

    def __call__(self, shapes: dict[str, tuple[int, ...]]) -> dict[str, np.ndarray]:
        torch = _torch()
        sizes = {name: int(np.prod(shape)) for name, shape in shapes.items()}
        storage = torch.UntypedStorage._new_shared(4 * max(1, sum(sizes.values())))
        self.flat = torch.empty(0, dtype=torch.float32).set_(storage)
        self.shapes = dict(shapes)
        out, start, whole = {}, 0, self.flat.numpy()
        for name, shape in shapes.items():
            out[name] = whole[start : start + sizes[name]].reshape(shape)
            start += sizes[name]
        return out


class _BatchParcel:
    """A batch on its way from a worker: pickles as the one shared buffer plus the small
    numpy arrays, and unpickles (in the training process) as the batch dict of tensors."""

    def __init__(self, batch: dict[str, Any], shared: _SharedBuffer) -> None:
        self.small = {k: v for k, v in batch.items() if k not in shared.shapes}
        self.flat, self.shapes = shared.flat, shared.shapes

    def __reduce__(self) -> tuple[Any, tuple[Any, ...]]:
        return _unpack_batch, (self.flat, self.shapes, self.small)

    def unpack(self) -> dict[str, Any]:
        return _unpack_batch(self.flat, self.shapes, self.small)


def _unpack_batch(
    flat: Any, shapes: dict[str, tuple[int, ...]], small: dict[str, Any]
) -> dict[str, Any]:
    torch = _torch()
    out: dict[str, Any] = {}
    start = 0
    for name, shape in shapes.items():
        size = int(np.prod(shape))
        out[name] = flat[start : start + size].view(shape)
        start += size
    for key, value in small.items():
        out[key] = torch.from_numpy(value) if isinstance(value, np.ndarray) else value
    return out


class _Windows:
    """``dataset.windows``: the windows as :class:`MeasureWindow` records, built on access
    (views sliced to the window, not fitted to ``window_frames``)."""

    def __init__(self, source: WindowSource) -> None:
        self._source = source

    def __len__(self) -> int:
        return len(self._source)

    def __getitem__(self, index: int) -> MeasureWindow:
        source = self._source
        arrays = source.raw(index)
        index = index % len(source)
        seq_id = source.spans.seq_ids[index]
        start = int(source.spans.frame_start[index])
        return MeasureWindow(
            seq_id=seq_id,
            measure=int(source.spans.measure[index]),
            frame_start=start,
            frame_stop=start + int(source.spans.length[index]),
            motion=arrays.get("motion"),
            audio=arrays.get("audio"),
            genre_onehot=source.genre_onehot(seq_id),
        )

    def __iter__(self) -> Iterator[MeasureWindow]:
        return (self[i] for i in range(len(self)))


class _WindowDataset:
    """Map-style dataset (``torch.utils.data.Dataset`` protocol) over a :class:`WindowSource`."""

    source: WindowSource

    def __len__(self) -> int:
        return len(self.source)

    @property
    def store(self) -> DanceStore:
        """The store (opened in this process on first use)."""
        return self.source.store

    @property
    def windows(self) -> _Windows:
        return _Windows(self.source)

    @property
    def lengths(self) -> np.ndarray:
        """(N,) int64 stored frames of each window (for LengthBucketSampler)."""
        return self.source.lengths

    @property
    def resampling(self) -> dict[str, Any]:
        """Per view, which columns ``fit="resample"`` resamples how (dancedata.read.window_fit)."""
        return self.source.resampling

    @property
    def columns(self) -> dict[str, Any]:
        """Per item key, which columns hold which array (name, start, stop, row shape)."""
        return self.source.columns

    def set_epoch(self, epoch: int) -> None:
        """The epoch the augmentations draw for (``training_loader`` passes each batch's epoch
        along, so persistent workers follow it too)."""
        self.source.set_epoch(epoch)

    def normalization(self, key: str = "motion") -> tuple[np.ndarray, np.ndarray]:
        """(D,) mean and std applied to item ``key`` (see :meth:`WindowSource.normalization`)."""
        return self.source.normalization(key)

    def denormalize(self, x: Any, key: str = "motion") -> Any:
        """Undo the normalisation of item ``key`` on (..., D) values: a tensor gives a float32
        tensor (on its device), an array a float32 array."""
        if key not in self.source.normalized:
            return x
        torch = _torch()
        if isinstance(x, torch.Tensor):
            mean, std = (torch.as_tensor(v, dtype=torch.float64) for v in self.normalization(key))
            from dancedata.compute.normalization import STD_FLOOR

            std = torch.where(std < STD_FLOOR, torch.ones_like(std), std)
            out = x.detach().to(torch.float64) * std.to(x.device) + mean.to(x.device)
            return out.to(torch.float32)
        return self.source.denormalize(x, key)

    def preload(self) -> _WindowDataset:
        """Read the views now, so that forked data-loader workers share them (see
        :meth:`WindowSource.preload`); returns the dataset."""
        self.source.preload()
        return self

    def batch(
        self, indices: list[int], multiple_of: int = 1, epoch: int | None = None
    ) -> dict[str, Any]:
        """Windows ``indices`` as one padded batch of tensors, equal to
        ``pad_collate([self[i] for i in indices])`` but built in one copy per window
        (:meth:`WindowSource.batch`); ``torch_batching.training_loader`` reads through it."""
        torch = _torch()
        out = self.source.batch(indices, multiple_of, epoch=epoch)
        for key, value in out.items():
            if isinstance(value, np.ndarray):
                out[key] = torch.from_numpy(value)
        return out

    def batch_parcel(
        self, indices: list[int], multiple_of: int = 1, epoch: int | None = None
    ) -> _BatchParcel:
        """:meth:`batch` for a data-loader worker to return: motion and audio are written
        straight into one shared-memory buffer and the small arrays travel inside the pickle,
        so handing the batch to the training process costs one shared-memory handle instead
        of one per tensor (seven: each is a round trip to the worker), and it unpickles there
        as the same dict as :meth:`batch` (:meth:`_BatchParcel.unpack` does it in-process)."""
        shared = _SharedBuffer()
        batch = self.source.batch(indices, multiple_of, alloc=shared, epoch=epoch)
        return _BatchParcel(batch, shared)

    def __getitem__(self, index: int) -> dict[str, Any]:
        torch = _torch()
        item = self.source.item(index)
        for key in ("motion", "audio", "genre", "mask"):
            if key in item:
                item[key] = torch.from_numpy(np.ascontiguousarray(item[key]))
        return item

    def __getitems__(self, indices: list[int]) -> list[dict[str, Any]]:
        """The items of one DataLoader batch, padded to the batch's longest window with zeros,
        each with ``mask`` (T,) bool (True on real frames) and ``length``, so torch's default
        collate stacks them. Items of fixed-length datasets (``window_frames``) are unchanged.
        ``pad_collate`` gives the same batch from these as from unpadded items."""
        items = [self[i] for i in indices]
        if self.source.window_frames is not None or not items:
            return items
        keys = [k for k in ("motion", "audio") if k in items[0]]
        total = max(int(item[keys[0]].shape[0]) for item in items)
        torch = _torch()
        for item in items:
            n = int(item[keys[0]].shape[0])
            for key in keys:
                value = item[key]
                if n < total:
                    padded = value.new_zeros((total, *value.shape[1:]))
                    padded[:n] = value
                    item[key] = padded
            item["mask"] = torch.arange(total) < n
        return items


class MeasureDataset(_WindowDataset):
    """Measure windows: one measure each by default, ``n_measures`` consecutive measures every
    ``hop_measures`` (default ``n_measures``) otherwise; fixed ``window_frames`` with ``fit``.

    Items: seq_id, measure (the first), frame_start, length (real frames), genre (G,),
    motion (T, D), audio (T, D') float32 tensors; with ``window_frames`` also mask (T,) bool."""

    def __init__(
        self,
        store: str | Path | DanceStore,
        split: str | None = None,
        scheme: str = "crossmodal",
        motion: ViewSpec | None = "fact_motion_225",
        audio: ViewSpec | None = "fact_audio_35",
        version: str | None = None,
        *,
        n_measures: int = 1,
        hop_measures: int | None = None,
        window_frames: int | None = None,
        fit: str = "resample",
        normalize: bool | Sequence[str] = False,
        augment: Sequence[Augmentation] | Augmentation | None = None,
        seed: int = 0,
    ) -> None:
        _torch()
        self.source = open_window_source(
            store, split, scheme, motion, audio, version,
            kind="measures", n_measures=n_measures, hop_measures=hop_measures,
            window_frames=window_frames, fit=fit, normalize=normalize, augment=augment,
            seed=seed,
        )  # fmt: skip


class SecondsDataset(_WindowDataset):
    """Sliding windows of ``seconds`` (ChoreoGraph's 1 s / 4 s / 8 s units) every
    ``hop_seconds`` (default ``seconds``), rounded to whole frames at each sequence's fps;
    fixed ``window_frames`` with ``fit``. Items as :class:`MeasureDataset`, measure −1."""

    def __init__(
        self,
        store: str | Path | DanceStore,
        split: str | None = None,
        seconds: float = 4.0,
        hop_seconds: float | None = None,
        scheme: str = "crossmodal",
        motion: ViewSpec | None = "fact_motion_225",
        audio: ViewSpec | None = "fact_audio_35",
        version: str | None = None,
        *,
        window_frames: int | None = None,
        fit: str = "resample",
        normalize: bool | Sequence[str] = False,
        augment: Sequence[Augmentation] | Augmentation | None = None,
        seed: int = 0,
    ) -> None:
        _torch()
        self.source = open_window_source(
            store, split, scheme, motion, audio, version,
            kind="seconds", seconds=seconds, hop_seconds=hop_seconds,
            window_frames=window_frames, fit=fit, normalize=normalize, augment=augment,
            seed=seed,
        )  # fmt: skip


class BeatDataset(_WindowDataset):
    """Windows of ``n_beats`` consecutive beats every ``hop_beats`` (default ``n_beats``),
    from the ``beats`` table (``dancedata segment STORE --tables measures,beats``): a beat spans
    from its frame to the next beat's. Items as :class:`MeasureDataset`, plus ``beat`` (the
    first beat's number; ``measure`` is its measure)."""

    def __init__(
        self,
        store: str | Path | DanceStore,
        split: str | None = None,
        scheme: str = "crossmodal",
        motion: ViewSpec | None = "fact_motion_225",
        audio: ViewSpec | None = "fact_audio_35",
        version: str | None = None,
        *,
        n_beats: int = 1,
        hop_beats: int | None = None,
        window_frames: int | None = None,
        fit: str = "resample",
        normalize: bool | Sequence[str] = False,
        augment: Sequence[Augmentation] | Augmentation | None = None,
        seed: int = 0,
    ) -> None:
        _torch()
        self.source = open_window_source(
            store, split, scheme, motion, audio, version,
            kind="beats", n_units=n_beats, hop_units=hop_beats,
            window_frames=window_frames, fit=fit, normalize=normalize, augment=augment,
            seed=seed,
        )  # fmt: skip


class PhraseDataset(_WindowDataset):
    """Windows of ``n_phrases`` consecutive phrases every ``hop_phrases`` (default
    ``n_phrases``), from the ``phrases`` table (``dancedata segment STORE --tables
    measures,phrases --phrase-measures 4``). Items as :class:`MeasureDataset`, plus ``phrase``
    (the first phrase's number; ``measure`` is its first measure)."""

    def __init__(
        self,
        store: str | Path | DanceStore,
        split: str | None = None,
        scheme: str = "crossmodal",
        motion: ViewSpec | None = "fact_motion_225",
        audio: ViewSpec | None = "fact_audio_35",
        version: str | None = None,
        *,
        n_phrases: int = 1,
        hop_phrases: int | None = None,
        window_frames: int | None = None,
        fit: str = "resample",
        normalize: bool | Sequence[str] = False,
        augment: Sequence[Augmentation] | Augmentation | None = None,
        seed: int = 0,
    ) -> None:
        _torch()
        self.source = open_window_source(
            store, split, scheme, motion, audio, version,
            kind="phrases", n_units=n_phrases, hop_units=hop_phrases,
            window_frames=window_frames, fit=fit, normalize=normalize, augment=augment,
            seed=seed,
        )  # fmt: skip
