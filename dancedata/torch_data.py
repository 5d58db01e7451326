"""PyTorch access to the windows of a store (torch is optional and imported on use).

    from dancedata.torch_data import MeasureDataset, SecondsDataset
    ds = MeasureDataset("data/stores/aist-demo", split="train")
    item = ds[0]   # {"motion": (T, 225) tensor, "audio": (T, 35) tensor, "genre": (G,), ...}

Measures differ in length when tempi differ (and by a frame at one tempo): batch them with
:func:`dancedata.torch_batching.pad_collate` (mask + lengths) and, to pad little,
:class:`dancedata.torch_batching.LengthBucketSampler`; or make every item ``window_frames``
long with ``fit="resample"|"crop"|"pad"`` (:mod:`dancedata.window_fit`). ``n_measures`` /
``hop_measures`` make windows of several measures; :class:`SecondsDataset` makes sliding
windows of ``seconds`` every ``hop_seconds`` (:mod:`dancedata.window_spans`).

Datasets pickle small and open the store lazily in each data-loader worker, so
``num_workers > 0`` works with fork and spawn.
"""

from __future__ import annotations

from collections.abc import Iterator
from pathlib import Path
from typing import Any

import numpy as np

from dancedata.loader import DanceStore
from dancedata.views.measures import MeasureWindow
from dancedata.window_dataset import WindowSource, open_window_source


def _torch() -> Any:
    try:
        import torch
    except ImportError:
        raise ImportError(
            "dancedata.torch_data needs PyTorch: pip install torch (or dancedata[stems])"
        ) from None
    return torch


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
        """Per view, which columns ``fit="resample"`` resamples how (dancedata.window_fit)."""
        return self.source.resampling

    def preload(self) -> _WindowDataset:
        """Read the views now, so that forked data-loader workers share them (see
        :meth:`WindowSource.preload`); returns the dataset."""
        self.source.preload()
        return self

    def batch(self, indices: list[int], multiple_of: int = 1) -> dict[str, Any]:
        """Windows ``indices`` as one padded batch of tensors, equal to
        ``pad_collate([self[i] for i in indices])`` but built in one copy per window
        (:meth:`WindowSource.batch`); ``torch_batching.training_loader`` reads through it."""
        torch = _torch()
        out = self.source.batch(indices, multiple_of)
        for key, value in out.items():
            if isinstance(value, np.ndarray):
                out[key] = torch.from_numpy(value)
        return out

    def __getitem__(self, index: int) -> dict[str, Any]:
        torch = _torch()
        item = self.source.item(index)
        for key in ("motion", "audio", "genre", "mask"):
            if key in item:
                item[key] = torch.from_numpy(np.ascontiguousarray(item[key]))
        return item


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
        motion: str | None = "fact_motion_225",
        audio: str | None = "fact_audio_35",
        version: str | None = None,
        *,
        n_measures: int = 1,
        hop_measures: int | None = None,
        window_frames: int | None = None,
        fit: str = "resample",
    ) -> None:
        _torch()
        self.source = open_window_source(
            store, split, scheme, motion, audio, version,
            kind="measures", n_measures=n_measures, hop_measures=hop_measures,
            window_frames=window_frames, fit=fit,
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
        motion: str | None = "fact_motion_225",
        audio: str | None = "fact_audio_35",
        version: str | None = None,
        *,
        window_frames: int | None = None,
        fit: str = "resample",
    ) -> None:
        _torch()
        self.source = open_window_source(
            store, split, scheme, motion, audio, version,
            kind="seconds", seconds=seconds, hop_seconds=hop_seconds,
            window_frames=window_frames, fit=fit,
        )  # fmt: skip
