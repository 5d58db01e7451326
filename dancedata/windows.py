"""Fast random access to measure windows: the thing a training loop asks for most.

:meth:`DanceStore.view` assembles a view per call with table and zarr lookups; fine for a few
calls, too slow for a data loader. :class:`MeasureWindows` does those lookups once: it holds
each window's global frame offsets as numpy arrays and the view's arrays flattened to 2-D (the
loader's cached whole arrays, reshaped without copying), so one window costs a few slices and
one concatenation.

    windows = store.measure_windows(split="train")       # fact_motion_225 + fact_audio_35
    motion, audio = windows[i]                            # (frames, 225), (frames, 35) float32
    for motion, audio in windows.sample(1000, seed=0): ...
"""

from __future__ import annotations

from collections.abc import Iterator
from typing import TYPE_CHECKING

import numpy as np

from dancedata.errors import StoreError

if TYPE_CHECKING:
    from dancedata.loader import DanceStore


class MeasureWindows:
    """Every measure of a split as (motion view, audio view) windows, by index."""

    def __init__(
        self,
        store: DanceStore,
        split: str | None = None,
        scheme: str = "crossmodal",
        motion: str | None = "fact_motion_225",
        audio: str | None = "fact_audio_35",
    ) -> None:
        from dancedata.loader import VIEWS

        for view in (motion, audio):
            if view is not None and view not in VIEWS:
                raise StoreError(f"unknown view {view!r}; known: {sorted(VIEWS)}")
        rows = store.measure_rows(split, scheme)
        seq_start: dict[str, int] = {}
        audio_start: dict[str, int] = {}
        audio_frames: dict[str, int] = {}
        for seq_id in {r["seq_id"] for r in rows}:
            seq = store.sequence(seq_id)
            seq_start[seq_id] = int(seq["frame_start"])
            n_audio = store.audio_frames(seq_id) if audio else 0
            audio_frames[seq_id] = n_audio
            if n_audio:
                track = store._music_rows[seq["music_id"]]
                audio_start[seq_id] = int(track["frame_start"]) + int(seq["audio_offset"])
        if audio:  # measures not fully covered by audio are left out, as iter_measures does
            rows = [r for r in rows if r["frame_stop"] <= audio_frames[r["seq_id"]]]
        self.seq_ids = [r["seq_id"] for r in rows]
        self.measure = np.array([r["measure"] for r in rows], dtype=np.int64)
        starts = np.array([r["frame_start"] for r in rows], dtype=np.int64)
        self.length = np.array([r["frame_stop"] for r in rows], dtype=np.int64) - starts
        self.motion_start = np.array([seq_start[s] for s in self.seq_ids], dtype=np.int64) + starts
        self.audio_start = (
            np.array([audio_start.get(s, 0) for s in self.seq_ids], dtype=np.int64) + starts
        )
        self._motion = self._parts(store, motion) if motion else None
        # Audio views are narrow (≤ 35 floats per frame): assemble the whole view once.
        self._audio = None
        if audio:
            parts = self._parts(store, audio)
            self._audio = np.concatenate([p for p in parts if p is not None], axis=1)

    @staticmethod
    def _parts(store: DanceStore, view: str) -> list[np.ndarray | None]:
        """The view's arrays as (frames, width) float32 (None for FACT's six zero columns)."""
        from dancedata.loader import VIEWS

        store._require_view_arrays(view)
        parts: list[np.ndarray | None] = []
        for kind, array in VIEWS[view]:
            if kind == "zeros6":
                parts.append(None)
                continue
            values = store._full(f"{kind}/{array}")
            values = values.reshape(values.shape[0], -1)
            parts.append(values if values.dtype == np.float32 else values.astype(np.float32))
        return parts

    def __len__(self) -> int:
        return len(self.seq_ids)

    def motion(self, i: int) -> np.ndarray:
        """(frames, D) float32 motion view of window ``i``."""
        if self._motion is None:
            raise StoreError("these windows were opened without a motion view")
        a = int(self.motion_start[i])
        b = a + int(self.length[i])
        return np.concatenate(
            [np.zeros((b - a, 6), np.float32) if p is None else p[a:b] for p in self._motion],
            axis=1,
        )

    def audio(self, i: int) -> np.ndarray:
        """(frames, D) float32 audio view of window ``i`` (a copy)."""
        if self._audio is None:
            raise StoreError("these windows were opened without an audio view")
        a = int(self.audio_start[i])
        return self._audio[a : a + int(self.length[i])].copy()

    def __getitem__(self, i: int) -> tuple[np.ndarray | None, np.ndarray | None]:
        return (
            self.motion(i) if self._motion is not None else None,
            self.audio(i) if self._audio is not None else None,
        )

    def sample(
        self, n: int, seed: int | None = None
    ) -> Iterator[tuple[np.ndarray | None, np.ndarray | None]]:
        """``n`` windows drawn uniformly at random (with replacement)."""
        rng = np.random.default_rng(seed)
        for i in rng.integers(0, len(self), size=n):
            yield self[int(i)]
