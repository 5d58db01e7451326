"""Windows of a store as numpy items: the engine behind the torch datasets, without torch.

A :class:`WindowSource` holds only small things (the store's locator string, the window
spans, the options), so it pickles in a few kilobytes: a data-loader worker started by
``spawn`` gets a copy that opens the store itself, on its first item; one started by
``fork`` inherits whatever the parent already loaded (zarr resets its event loop after a
fork). Views are read through the reader's whole-array cache
(:meth:`_SequenceReader.whole_array`), so after the first item of a process a window costs a
few numpy slices.

:func:`open_window_source` is what the datasets call: the split checked (an unknown or empty
split is its own error), the source made, and a split that yields no windows refused loudly.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from pathlib import Path
from typing import Any

import numpy as np

from dancedata.compute.augment import mirror_pairs
from dancedata.compute.normalization import denormalize, normalize
from dancedata.compute.view_columns import part_widths, stack_parts
from dancedata.errors import InputError, StoreError
from dancedata.read.loader import DanceStore
from dancedata.read.views.assemble import require_view_arrays
from dancedata.read.views.layouts import ViewSpec, check_view_names, spec_label, spec_parts
from dancedata.read.window_augment import Mirror, Rig, Yaw, check_augmentable, mirror_rows, yaw_rows
from dancedata.read.window_fit import FIT_MODES, ColumnPart, column_plan, fit_window
from dancedata.read.window_spans import (
    UNIT_TABLES,
    WindowSpans,
    measure_spans,
    second_spans,
    unit_spans,
)
from dancedata.store.layout import warn_once

KINDS = ("measures", "beats", "phrases", "seconds")
AUGMENTATIONS = {"mirror": Mirror, "yaw": Yaw}
Augmentation = str | Mirror | Yaw

Allocate = Callable[[dict[str, tuple[int, ...]]], dict[str, np.ndarray]]
"""Shapes by name → zeroed float32 arrays of those shapes (see :meth:`WindowSource.batch`)."""


def _zeros(shapes: dict[str, tuple[int, ...]]) -> dict[str, np.ndarray]:
    return {name: np.zeros(shape, np.float32) for name, shape in shapes.items()}


def view_plan(store: DanceStore, spec: ViewSpec, key: str) -> list[ColumnPart]:
    """The column plan of a view spec on ``store`` (names, row shapes, resamplers), from the
    arrays' metadata only; StoreError when a part is not of the item's ``key`` group (motion
    arrays run on motion frames, audio arrays on music frames: one item key holds one)."""
    parts = spec_parts(spec)
    wrong = [f"{k}/{a}" for k, a in parts if k not in (key, "zeros6")]
    if wrong:
        other = "audio" if key == "motion" else "motion"
        raise StoreError(
            f"{key}={spec_label(spec)!r} holds {', '.join(wrong)}: {key}= takes {key} views and "
            f"{key}/ arrays; put {other}/ arrays in {other}=",
            store.path,
        )
    require_view_arrays(store, spec)
    shapes, dtypes, widths = [], [], []
    for kind, array in parts:
        if kind == "zeros6":
            shapes.append((6,))
            dtypes.append(None)
            widths.append(6)
            continue
        meta = store.zarr(f"{kind}/{array}")
        shapes.append(tuple(int(d) for d in meta.shape[1:]))
        dtypes.append(np.dtype(meta.dtype))
        widths.append(int(np.prod(shapes[-1], dtype=np.int64)))
    return column_plan(parts, widths, shapes, dtypes)


class _ViewRows:
    """One view spec of one store, flattened to (frames, width) parts for fast slicing."""

    def __init__(self, store: DanceStore, spec: ViewSpec, plan: list[ColumnPart]) -> None:
        self.parts = store.view_parts(spec)
        self.plan = plan
        if part_widths(self.parts) != [p.stop - p.start for p in plan]:
            raise StoreError(f"view {spec_label(spec)!r} changed shape while read", store.path)

    def rows(self, start: int, stop: int) -> np.ndarray:
        return stack_parts(self.parts, start, stop)


def _augmentations(augment: Sequence[Augmentation] | Augmentation | None) -> tuple:
    if augment is None:
        return ()
    items = [augment] if isinstance(augment, str | Mirror | Yaw) else list(augment)
    out = []
    for op in items:
        if isinstance(op, str):
            if op not in AUGMENTATIONS:
                raise InputError(
                    f"unknown augmentation {op!r}; known: {', '.join(AUGMENTATIONS)} "
                    "(or dancedata.read.window_augment.Mirror(p=...), Yaw(max_deg=...))"
                )
            op = AUGMENTATIONS[op]()
        if not isinstance(op, Mirror | Yaw):
            raise InputError(f"an augmentation is 'mirror', 'yaw', Mirror or Yaw (got {op!r})")
        in_range = 0.0 <= op.p <= 1.0 if isinstance(op, Mirror) else 0.0 <= op.max_deg <= 360
        if not in_range or (isinstance(op, Mirror) and op.lateral_axis not in (0, 1, 2)):
            raise InputError(f"augmentation {op!r} is out of range (p in [0, 1], axes 0-2)")
        out.append(op)
    return tuple(out)


def store_rig(store: DanceStore) -> Rig:
    """The rig facts augmentation needs, from the motion group's attributes."""
    attrs = store.group_attrs("motion") if store.array_names() else {}
    skeleton = attrs.get("skeleton") if isinstance(attrs.get("skeleton"), dict) else {}
    joints = [str(j) for j in skeleton.get("joints") or []]
    parents = list(skeleton.get("parents") or [])
    root = parents.index(-1) if -1 in parents else 0
    up = {"x": 0, "y": 1, "z": 2}.get(str(attrs.get("up_axis", "y")).lower(), 1)
    pairs, problem = None, ""
    try:
        pairs = mirror_pairs(joints) if joints else None
        if pairs is None:
            problem = "the store's motion attributes name no joints"
        elif np.array_equal(pairs, np.arange(len(joints))):
            pairs, problem = None, f"no left/right joint pairs found in the rig's names {joints}"
    except ValueError as error:
        problem = f"{error} ({joints})"
    orders: tuple[str, ...] = ()
    if store.has_array("motion/euler"):
        order = store.zarr("motion/euler").attrs.get("order")
        n = int(store.zarr("motion/euler").shape[1])
        orders = tuple(order) if isinstance(order, list) else (str(order),) * n
    return Rig(pairs, root, up, orders, problem)


class WindowSource:
    """Windows of ``split`` as dicts of numpy arrays (see :meth:`item`).

    ``motion`` / ``audio`` are view specs: a paper view (``fact_motion_225``), an array path
    (``motion/quat``, ``audio/stft_frames``) or a list of them, side by side
    (:mod:`dancedata.read.views.layouts`). ``kind="measures"`` takes ``n_measures`` /
    ``hop_measures``; ``kind="beats"`` / ``"phrases"`` take ``n_units`` / ``hop_units``
    (windows of consecutive beats or phrases); ``kind="seconds"`` takes ``seconds`` /
    ``hop_seconds`` (:mod:`dancedata.read.window_spans`). ``window_frames`` with ``fit`` makes every
    item that many frames (:mod:`dancedata.read.window_fit`). ``normalize`` (True: every part but
    events, masks and FACT's zero columns; or a list of array paths) applies the version's
    normalisation table (``dancedata stats``) and :meth:`denormalize` undoes it. ``augment``
    ("mirror", "yaw", or :class:`~dancedata.read.window_augment.Mirror` /
    :class:`~dancedata.read.window_augment.Yaw`) transforms each item, its random draws from
    ``default_rng([seed, epoch, window index])``. An item is: stored rows → augmentations in
    order → ``fit`` → normalisation."""

    def __init__(
        self,
        store: str | Path | DanceStore,
        split: str | None = None,
        scheme: str = "crossmodal",
        motion: ViewSpec | None = "fact_motion_225",
        audio: ViewSpec | None = "fact_audio_35",
        version: str | None = None,
        *,
        kind: str = "measures",
        n_measures: int = 1,
        hop_measures: int | None = None,
        n_units: int = 1,
        hop_units: int | None = None,
        seconds: float = 4.0,
        hop_seconds: float | None = None,
        window_frames: int | None = None,
        fit: str = "resample",
        normalize: bool | Sequence[str] = False,
        augment: Sequence[Augmentation] | Augmentation | None = None,
        seed: int = 0,
    ) -> None:
        check_view_names(motion, audio)
        if motion is None and audio is None:
            raise InputError("a window dataset needs a motion view, an audio view or both")
        if fit not in FIT_MODES:
            raise InputError(f"fit must be one of {', '.join(FIT_MODES)} (got {fit!r})")
        if window_frames is not None and window_frames < 1:
            raise InputError(f"window_frames must be ≥ 1 (got {window_frames})")
        if kind not in KINDS:
            raise InputError(f"kind must be one of {', '.join(KINDS)} (got {kind!r})")
        if int(seed) < 0:
            raise InputError(f"seed must be ≥ 0 (got {seed})")
        opened = store if isinstance(store, DanceStore) else DanceStore(store, version)
        self.path = opened.path
        self.locator = opened.locator  # what workers reopen: a URL stays a URL when pickled
        self.version = opened.version
        self.split, self.scheme = split, scheme
        self.motion_view, self.audio_view = motion, audio
        self.window_frames, self.fit = window_frames, fit
        self.kind, self.seed, self.epoch = kind, int(seed), 0
        self.plans: dict[str, list[ColumnPart]] = {}
        for key, spec in (("motion", motion), ("audio", audio)):
            if spec is not None:
                self.plans[key] = view_plan(opened, spec, key)
        if kind == "measures":
            self.spans: WindowSpans = measure_spans(
                opened, split, scheme, audio is not None, n_measures, hop_measures
            )
        elif kind in UNIT_TABLES:
            self.spans = unit_spans(
                opened, kind, split, scheme, audio is not None, n_units, hop_units
            )
        else:
            self.spans = second_spans(
                opened, split, scheme, audio is not None, seconds, hop_seconds
            )
        several = n_measures if kind == "measures" else n_units
        if not len(self.spans) and (kind == "seconds" or several > 1):
            what = f"{seconds} s" if kind == "seconds" else f"{several}-{kind[:-1]}"
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
        self.augment = _augmentations(augment)
        self.rig: Rig | None = None
        if self.augment:
            self.rig = store_rig(opened)
            for op in self.augment:
                for plan in self.plans.values():
                    check_augmentable(plan, op, self.rig)
        self.normalized: dict[str, list[str]] = {}
        self._norm: dict[str, tuple[np.ndarray, np.ndarray]] = {}
        if normalize is not False and normalize is not None:
            self._set_normalization(opened, normalize)
        self.genres = opened.genres
        self._store: DanceStore | None = opened
        self._views: dict[str, _ViewRows] | None = None
        self._offsets: dict[str, tuple[int, int]] | None = None

    def _set_normalization(self, store: DanceStore, normalize: bool | Sequence[str]) -> None:
        """Per item key, the (D,) mean and std to apply: the stored statistics on the chosen
        parts' columns, 0 and 1 on the others."""
        names = [p.name for plan in self.plans.values() for p in plan if p.name != "zeros6"]
        if normalize is True:
            chosen = [
                p.name
                for plan in self.plans.values()
                for p in plan
                if p.method not in ("zeros", "event", "nearest")
            ]
        else:
            chosen = [normalize] if isinstance(normalize, str) else list(normalize)
            unknown = [n for n in chosen if n not in names]
            if unknown:
                raise InputError(
                    f"normalize names {', '.join(unknown)}, not a part of this dataset "
                    f"(its parts: {', '.join(names)})"
                )
        for key, plan in self.plans.items():
            width = plan[-1].stop if plan else 0
            mean, std = np.zeros(width), np.ones(width)
            for part in plan:
                if part.name not in chosen:
                    continue
                stats = store.normalization(part.name)
                if stats.mean.size != part.stop - part.start:
                    raise StoreError(
                        f"the normalization of {part.name} has {stats.mean.size} columns, the "
                        f"array {part.stop - part.start} (rerun `dancedata stats`)",
                        store.path,
                    )
                mean[part.start : part.stop] = stats.mean.reshape(-1)
                std[part.start : part.stop] = stats.std.reshape(-1)
            self._norm[key] = (mean, std)
            self.normalized[key] = [p.name for p in plan if p.name in chosen]

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
                views["motion"] = _ViewRows(store, self.motion_view, self.plans["motion"])
            if self.audio_view:
                views["audio"] = _ViewRows(store, self.audio_view, self.plans["audio"])
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

    def set_epoch(self, epoch: int) -> None:
        """The epoch the augmentations draw for when a call names none (see :meth:`item`)."""
        if int(epoch) < 0:
            raise InputError(f"epoch must be ≥ 0 (got {epoch})")
        self.epoch = int(epoch)

    # -- windows -------------------------------------------------------------------------------
    def __len__(self) -> int:
        return len(self.spans)

    @property
    def lengths(self) -> np.ndarray:
        """(N,) int64 frames of each window as stored (before ``window_frames``)."""
        return self.spans.length

    @property
    def resampling(self) -> dict[str, list[ColumnPart]]:
        """Per item key (motion, audio), its columns: array name, column range, resampler
        (used with ``fit="resample"``) and the array's row shape."""
        return dict(self.plans)

    @property
    def columns(self) -> dict[str, list[ColumnPart]]:
        """Per item key, which columns hold which array (the same plan as :attr:`resampling`):
        ``item["motion"][:, p.start:p.stop].reshape(-1, *p.shape)`` is array ``p.name``."""
        return dict(self.plans)

    @property
    def per_item(self) -> bool:
        """Whether items need more than a slice (fixed length, augmentation, normalisation)."""
        return self.window_frames is not None or bool(self.augment) or bool(self._norm)

    def normalization(self, key: str = "motion") -> tuple[np.ndarray, np.ndarray]:
        """(D,) float64 mean and std applied to item ``key`` (0 and 1 on columns left as
        they are); StoreError when the dataset was made without ``normalize``."""
        if key not in self._norm:
            raise StoreError(f"this dataset does not normalise {key!r} (normalize=...)", self.path)
        return self._norm[key]

    def denormalize(self, x: np.ndarray, key: str = "motion") -> np.ndarray:
        """The inverse of the normalisation of item ``key``, on (..., D) values (a model's
        output before export): x · std + mean, float32; unchanged when ``key`` is not
        normalised."""
        if key not in self._norm:
            return np.asarray(x, dtype=np.float32)
        mean, std = self._norm[key]
        return denormalize(x, mean, std)

    def augment_rows(self, rows: np.ndarray, key: str, index: int, epoch: int | None = None):
        """(L, D) stored rows of item ``key`` with the augmentations of window ``index`` in
        ``epoch`` (default: the current one) applied: the draws come from
        ``default_rng([seed, epoch, index])``, one per augmentation in order (a uniform for a
        Mirror's coin, an angle for a Yaw), so the same seed, epoch and index give the same
        item in any process."""
        if not self.augment:
            return rows
        rig = self.rig if self.rig is not None else store_rig(self.store)
        epoch = self.epoch if epoch is None else int(epoch)
        rng = np.random.default_rng([self.seed, epoch, int(index) % len(self)])
        plan = self.plans[key]
        for op in self.augment:
            if isinstance(op, Mirror):
                if rng.random() < op.p:
                    rows = mirror_rows(rows, plan, rig, op.lateral_axis)
            else:
                angle = np.deg2rad(rng.uniform(-op.max_deg, op.max_deg))
                up = rig.up_axis if op.up_axis is None else op.up_axis
                rows = yaw_rows(rows, plan, Rig(rig.pairs, rig.root, up, rig.euler_orders), angle)
        return rows

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

    def _unit_keys(self, rows: list[int] | int) -> dict[str, Any]:
        if self.spans.unit is None:
            return {}
        name = UNIT_TABLES[self.kind]
        value = self.spans.unit[rows]
        return {name: value.copy() if isinstance(value, np.ndarray) else int(value)}

    def batch(
        self,
        indices: list[int],
        multiple_of: int = 1,
        alloc: Allocate | None = None,
        epoch: int | None = None,
    ) -> dict[str, Any]:
        """Windows ``indices`` as one padded batch, the numpy form of
        ``torch_batching.pad_collate([item(i) for i in indices])``: seq_id (list), measure,
        frame_start, lengths (B,) int64, genre (B, G), motion / audio (B, T, D) float32 zero
        after each window's end, mask (B, T) bool (beat and phrase windows add beat / phrase
        (B,)). Slice-only datasets copy each view part once, straight into its place in the
        batch. ``alloc`` makes the zeroed float32 motion / audio arrays from their shapes, all
        at once (default ``np.zeros``; the torch dataset passes one that places them in one
        shared-memory buffer in workers). ``epoch`` is the augmentations' (default: current)."""
        from dancedata.read.batching import lengths_mask, padded_length

        rows = [i % len(self) for i in indices]
        alloc = alloc or _zeros
        if self.per_item:
            items = [self.item(i, epoch) for i in rows]
            lengths = [it["length"] for it in items]
            frames = [it[next(iter(self.plans))].shape[0] for it in items]
            total = padded_length(frames, multiple_of)
            names = [name for name in ("motion", "audio") if name in items[0]]
            out: dict[str, Any] = alloc(
                {name: (len(items), total, items[0][name].shape[1]) for name in names}
            )
            for name in names:
                for b, it in enumerate(items):
                    out[name][b, : it[name].shape[0]] = it[name]
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
            **self._unit_keys(rows),
        )
        out["length"] = out["lengths"]  # the key DataLoader's default collate batches carry
        return out

    def genre_onehot(self, seq_id: str) -> np.ndarray:
        out = np.zeros(len(self.genres), dtype=np.float32)
        genre = self.store.sequence(seq_id).get("genre")
        if genre in self.genres:
            out[self.genres.index(genre)] = 1.0
        return out

    def item(self, i: int, epoch: int | None = None) -> dict[str, Any]:
        """Window ``i``: seq_id, measure (of its first frame; −1 for second windows), beat or
        phrase (the first; beat and phrase windows only), frame_start (on the sequence's frame
        axis), length (real frames in the item), genre (G,), motion and/or audio (frames, D)
        float32; with ``window_frames``, also mask (W,) bool. ``epoch`` is the augmentations'
        (default: the current one, :meth:`set_epoch`)."""
        arrays = self.raw(i)
        i = i % len(self)
        seq_id = self.spans.seq_ids[i]
        item: dict[str, Any] = {
            "seq_id": seq_id,
            "measure": int(self.spans.measure[i]),
            **self._unit_keys(i),
            "frame_start": int(self.spans.frame_start[i]),
            "length": int(self.spans.length[i]),
            "genre": self.genre_onehot(seq_id),
        }
        for name in arrays:
            arrays[name] = self.augment_rows(arrays[name], name, i, epoch)
        if self.window_frames is not None:
            for name, rows in arrays.items():
                plan = self.plans[name]
                arrays[name], kept = fit_window(rows, plan, self.window_frames, self.fit)
            item["length"] = kept
            item["mask"] = np.arange(self.window_frames) < kept
        for name, (mean, std) in self._norm.items():
            arrays[name] = normalize(arrays[name], mean, std)
            arrays[name][item["length"] :] = 0.0  # padding stays zero
        item.update(arrays)
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
    motion: ViewSpec | None,
    audio: ViewSpec | None,
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
