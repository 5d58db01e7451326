"""Windows of a store as numpy items: the engine behind the torch datasets, without torch.

A :class:`WindowSource` holds only small things (the store's locator string, the window
spans, the options), so it pickles in a few kilobytes: a data-loader worker started by
``spawn`` gets a copy that opens the store itself, on its first item; one started by
``fork`` inherits whatever the parent already loaded (zarr resets its event loop after a
fork). Views are read through the reader's whole-array cache
(:meth:`SequenceReader.whole_array`), so after the first item of a process a window costs a
few numpy slices.

:func:`open_window_source` is what the datasets call: the split checked (an unknown or empty
split is its own error), the source made, and a split that yields no windows refused loudly.
"""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np

from dancedata.compute.view_columns import part_widths, stack_parts
from dancedata.errors import InputError, StoreError
from dancedata.loader import DanceStore
from dancedata.store.layout import warn_once
from dancedata.views.assemble import require_view_arrays
from dancedata.views.layouts import VIEWS, check_view_names
from dancedata.window_fit import FIT_MODES, ColumnPart, column_plan, fit_window
from dancedata.window_spans import WindowSpans, measure_spans, second_spans

Allocate = Callable[[dict[str, tuple[int, ...]]], dict[str, np.ndarray]]
"""Shapes by name → zeroed float32 arrays of those shapes (see :meth:`WindowSource.batch`)."""


def _zeros(shapes: dict[str, tuple[int, ...]]) -> dict[str, np.ndarray]:
    return {name: np.zeros(shape, np.float32) for name, shape in shapes.items()}


class _ViewRows:
    """One view of one store, flattened to (frames, width) parts for fast slicing."""

    def __init__(self, store: DanceStore, view: str) -> None:
        self.parts = store.view_parts(view)
        self.plan = column_plan(VIEWS[view], part_widths(self.parts))

    def rows(self, start: int, stop: int) -> np.ndarray:
        return stack_parts(self.parts, start, stop)


class WindowSource:
    """Windows of ``split`` as dicts of numpy arrays (see :meth:`item`).

    ``kind="measures"`` takes ``n_measures`` / ``hop_measures``; ``kind="seconds"`` takes
    ``seconds`` / ``hop_seconds`` (:mod:`dancedata.window_spans`). ``window_frames`` with
    ``fit`` makes every item that many frames (:mod:`dancedata.window_fit`)."""

    def __init__(
        self,
        store: str | Path | DanceStore,
        split: str | None = None,
        scheme: str = "crossmodal",
        motion: str | None = "fact_motion_225",
        audio: str | None = "fact_audio_35",
        version: str | None = None,
        *,
        kind: str = "measures",
        n_measures: int = 1,
        hop_measures: int | None = None,
        seconds: float = 4.0,
        hop_seconds: float | None = None,
        window_frames: int | None = None,
        fit: str = "resample",
    ) -> None:
        check_view_names(motion, audio)
        if motion is None and audio is None:
            raise InputError("a window dataset needs a motion view, an audio view or both")
        if fit not in FIT_MODES:
            raise InputError(f"fit must be one of {', '.join(FIT_MODES)} (got {fit!r})")
        if window_frames is not None and window_frames < 1:
            raise InputError(f"window_frames must be ≥ 1 (got {window_frames})")
        opened = store if isinstance(store, DanceStore) else DanceStore(store, version)
        self.path = opened.path
        self.locator = opened.locator  # what workers reopen: a URL stays a URL when pickled
        self.version = opened.version
        self.split, self.scheme = split, scheme
        self.motion_view, self.audio_view = motion, audio
        self.window_frames, self.fit = window_frames, fit
        for view in (motion, audio):
            if view is not None:
                require_view_arrays(opened, view)
        if kind == "measures":
            self.spans: WindowSpans = measure_spans(
                opened, split, scheme, audio is not None, n_measures, hop_measures
            )
        elif kind == "seconds":
            self.spans = second_spans(
                opened, split, scheme, audio is not None, seconds, hop_seconds
            )
        else:
            raise InputError(f"kind must be 'measures' or 'seconds' (got {kind!r})")
        if not len(self.spans) and (kind == "seconds" or n_measures > 1):
            what = f"{seconds} s" if kind == "seconds" else f"{n_measures}-measure"
            raise InputError(
                f"no {what} windows in split {split!r} of {self.path} (version {self.version}):"
                " no sequence (with music, when an audio view is asked for) is long enough"
            )
        if window_frames is not None and fit == "pad" and len(self.spans):
            longest = int(self.spans.length.max())
            if longest > window_frames:
                i = int(self.spans.length.argmax())
                raise InputError(
                    f"fit='pad' never drops frames, but window {i} ({self.spans.seq_ids[i]}, "
                    f"frame {int(self.spans.frame_start[i])}) has {longest} frames > "
                    f"window_frames={window_frames}; use fit='crop' or 'resample', or "
                    f"window_frames ≥ {longest}"
                )
        self.genres = opened.genres
        self._store: DanceStore | None = opened
        self._views: dict[str, _ViewRows] | None = None
        self._offsets: dict[str, tuple[int, int]] | None = None

    # -- process-local state (dropped when pickled, rebuilt on first use) ----------------------
    def __getstate__(self) -> dict[str, Any]:
        state = dict(self.__dict__)
        state.update(_store=None, _views=None, _offsets=None)
        return state

    @property
    def store(self) -> DanceStore:
        """The store, opened in this process on first use."""
        if self._store is None:
            self._store = DanceStore(self.locator, self.version)
        return self._store

    def _ensure_views(self) -> tuple[dict[str, _ViewRows], dict[str, tuple[int, int]]]:
        if self._views is None or self._offsets is None:
            store = self.store
            views = {}
            if self.motion_view:
                views["motion"] = _ViewRows(store, self.motion_view)
            if self.audio_view:
                views["audio"] = _ViewRows(store, self.audio_view)
            offsets = {}
            for seq_id in set(self.spans.seq_ids):
                audio0 = store.audio_start(seq_id) if self.audio_view else 0
                offsets[seq_id] = (int(store.sequence(seq_id)["frame_start"]), audio0)
            self._views, self._offsets = views, offsets
        return self._views, self._offsets

    def preload(self) -> WindowSource:
        """Read the views into this process now. Before a DataLoader starts ``fork`` workers,
        this makes them share one copy of the arrays (copy-on-write) instead of each reading
        its own; with ``spawn`` it does not help (the pickle carries no arrays)."""
        self._ensure_views()
        return self

    # -- windows -------------------------------------------------------------------------------
    def __len__(self) -> int:
        return len(self.spans)

    @property
    def lengths(self) -> np.ndarray:
        """(N,) int64 frames of each window as stored (before ``window_frames``)."""
        return self.spans.length

    @property
    def resampling(self) -> dict[str, list[ColumnPart]]:
        """Per view, which columns are resampled how (used with ``fit="resample"``)."""
        views, _ = self._ensure_views()
        return {name: rows.plan for name, rows in views.items()}

    def raw(self, i: int) -> dict[str, np.ndarray]:
        """Window ``i``'s view rows as stored: {"motion": (L, D), "audio": (L, D')}."""
        if not -len(self) <= i < len(self):
            raise IndexError(f"window {i} out of range (0..{len(self) - 1})")
        i = i % len(self)
        views, offsets = self._ensure_views()
        seq_id = self.spans.seq_ids[i]
        start, length = int(self.spans.frame_start[i]), int(self.spans.length[i])
        motion0, audio0 = offsets[seq_id]
        out = {}
        if "motion" in views:
            out["motion"] = views["motion"].rows(motion0 + start, motion0 + start + length)
        if "audio" in views:
            out["audio"] = views["audio"].rows(audio0 + start, audio0 + start + length)
        return out

    def batch(
        self, indices: list[int], multiple_of: int = 1, alloc: Allocate | None = None
    ) -> dict[str, Any]:
        """Windows ``indices`` as one padded batch, the numpy form of
        ``torch_batching.pad_collate([item(i) for i in indices])``: seq_id (list), measure,
        frame_start, lengths (B,) int64, genre (B, G), motion / audio (B, T, D) float32 zero
        after each window's end, mask (B, T) bool. Without ``window_frames`` each view part is
        copied once, straight into its place in the batch. ``alloc`` makes the zeroed float32
        motion / audio arrays from their shapes, all at once (default ``np.zeros``; the torch
        dataset passes one that places them in one shared-memory buffer in workers)."""
        from dancedata.batching import lengths_mask, padded_length

        rows = [i % len(self) for i in indices]
        alloc = alloc or _zeros
        if self.window_frames is not None:
            items = [self.item(i) for i in rows]
            lengths = [it["length"] for it in items]
            total = padded_length([self.window_frames], multiple_of)
            names = [name for name in ("motion", "audio") if name in items[0]]
            out: dict[str, Any] = alloc(
                {name: (len(items), total, items[0][name].shape[1]) for name in names}
            )
            for name in names:
                for b, it in enumerate(items):
                    out[name][b, : self.window_frames] = it[name]
        else:
            views, offsets = self._ensure_views()
            lengths = [int(self.spans.length[i]) for i in rows]
            total = padded_length(lengths, multiple_of)
            widths = {name: part_widths(view.parts) for name, view in views.items()}
            out = alloc({name: (len(rows), total, sum(w)) for name, w in widths.items()})
            for name, view in views.items():
                dest = out[name]
                for b, i in enumerate(rows):
                    base = offsets[self.spans.seq_ids[i]][0 if name == "motion" else 1]
                    a = base + int(self.spans.frame_start[i])
                    n = lengths[b]
                    col = 0
                    for part, width in zip(view.parts, widths[name], strict=True):
                        if part is not None:
                            dest[b, :n, col : col + width] = part[a : a + n]
                        col += width
        seq_ids = [self.spans.seq_ids[i] for i in rows]
        out.update(
            seq_id=seq_ids,
            measure=self.spans.measure[rows].copy(),
            frame_start=self.spans.frame_start[rows].copy(),
            genre=np.stack([self.genre_onehot(s) for s in seq_ids]),
            lengths=np.asarray(lengths, dtype=np.int64),
            mask=lengths_mask(lengths, total),
        )
        return out

    def genre_onehot(self, seq_id: str) -> np.ndarray:
        out = np.zeros(len(self.genres), dtype=np.float32)
        genre = self.store.sequence(seq_id).get("genre")
        if genre in self.genres:
            out[self.genres.index(genre)] = 1.0
        return out

    def item(self, i: int) -> dict[str, Any]:
        """Window ``i``: seq_id, measure (first; −1 for second windows), frame_start (on the
        sequence's frame axis), length (real frames in the item), genre (G,), motion and/or
        audio (frames, D) float32; with ``window_frames``, also mask (W,) bool."""
        arrays = self.raw(i)
        i = i % len(self)
        seq_id = self.spans.seq_ids[i]
        item: dict[str, Any] = {
            "seq_id": seq_id,
            "measure": int(self.spans.measure[i]),
            "frame_start": int(self.spans.frame_start[i]),
            "length": int(self.spans.length[i]),
            "genre": self.genre_onehot(seq_id),
        }
        if self.window_frames is None:
            item.update(arrays)
            return item
        views, _ = self._ensure_views()
        for name, rows in arrays.items():
            item[name], kept = fit_window(rows, views[name].plan, self.window_frames, self.fit)
        item["length"] = kept
        item["mask"] = np.arange(self.window_frames) < kept
        return item


def open_split(
    store: str | Path | DanceStore, version: str | None, split: str | None, scheme: str
) -> DanceStore:
    """The store opened (once), after checking that ``split`` names sequences: StoreError for
    an unknown split or one with no sequences, with what its split file listed."""
    opened = store if isinstance(store, DanceStore) else DanceStore(store, version)
    if split is not None and not opened.split_members(split, scheme):
        raise StoreError(opened.empty_split_reason(split, scheme), opened.path)
    return opened


def check_window_count(
    store: DanceStore, split: str | None, scheme: str, with_audio: bool, count: int
) -> None:
    """Loud, not empty (for the window datasets): a StoreError naming the reason when ``split``
    yields no windows, and a one-line warning on stderr when audio windows leave out sequences
    of the split that have no music."""
    seq_ids = store.seq_ids(split, scheme)  # an unknown split is an error there
    if split is not None and not seq_ids:
        raise StoreError(store.empty_split_reason(split, scheme), store.path)
    silent = [s for s in seq_ids if store.audio_frames(s) == 0] if with_audio else []
    where = f"split {split!r} of scheme {scheme!r}" if split else "the store"
    if count == 0:
        if silent and len(silent) == len(seq_ids):
            first = store.no_music_reason(silent[0])
            reason = (
                f"none of its {len(seq_ids)} sequences has music ({first}); read motion only "
                "with audio=None"
            )
        else:
            reason = f"none of its {len(seq_ids)} sequences is long enough for one window"
        raise StoreError(f"no windows in {where}, version {store.version}: {reason}", store.path)
    if silent:
        warn_once(
            f"{store.path}: audio windows leave out {len(silent)} of {len(seq_ids)} sequences of "
            f"{where} that have no music (e.g. {store.no_music_reason(silent[0])}); "
            "audio=None keeps them"
        )


def open_window_source(
    store: str | Path | DanceStore,
    split: str | None,
    scheme: str,
    motion: str | None,
    audio: str | None,
    version: str | None,
    **windows: Any,
) -> WindowSource:
    """A :class:`WindowSource` of ``split`` for a dataset: the split checked first (an unknown
    or empty split is its own error, see :func:`open_split`), the store opened once, and the
    result refused when it has no window (:func:`check_window_count`). ``windows`` are
    :class:`WindowSource`'s keyword options (kind, n_measures, seconds, window_frames, fit…)."""
    opened = open_split(store, version, split, scheme)
    source = WindowSource(opened, split, scheme, motion, audio, version, **windows)
    check_window_count(source.store, split, scheme, audio is not None, len(source))
    return source
