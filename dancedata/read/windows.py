"""Fast random access to measure windows: the thing a training loop asks for most.

:meth:`DanceStore.view` assembles a view per call with table and zarr lookups; fine for a few
calls, too slow for a data loader. :func:`dancedata.read.views.measures.measure_windows` (behind
:meth:`DanceStore.measure_windows`) does those lookups once and hands :class:`MeasureWindows`
the results: each window's global frame offsets as numpy arrays and the view's arrays
flattened to 2-D (the reader's cached whole arrays, reshaped without copying), so one window
costs a few slices and one concatenation. This module only slices arrays; it never reads the
store.

    windows = store.measure_windows(split="train")       # fact_motion_225 + fact_audio_35
    motion, audio = windows[i]                            # (frames, 225), (frames, 35) float32
    for motion, audio in windows.sample(1000, seed=0): ...
"""

from __future__ import annotations

from collections.abc import Iterator

import numpy as np

from dancedata.compute.view_columns import stack_parts
from dancedata.errors import StoreError


class MeasureWindows:
    """Every measure of a split as (motion view, audio view) windows, by index.

    Built from arrays, not from a store (:func:`dancedata.read.views.measures.measure_windows`
    does the table lookups and passes the results here), so this module knows nothing of the
    reader. One entry per window in ``seq_ids``, ``measure``, ``length`` (frames),
    ``motion_start`` and ``audio_start`` (global row offsets into the motion and audio arrays).
    ``motion_parts`` are the motion view's arrays as (frames, width) float32, None for FACT's
    six zero columns; ``audio`` is the whole audio view as one (frames, width) float32 array.
    Either is None when the windows were opened without that view.
    """

    def __init__(
        self,
        seq_ids: list[str],
        measure: np.ndarray,
        length: np.ndarray,
        motion_start: np.ndarray,
        audio_start: np.ndarray,
        motion_parts: list[np.ndarray | None] | None,
        audio: np.ndarray | None,
    ) -> None:
        self.seq_ids = seq_ids
        self.measure = measure
        self.length = length
        self.motion_start = motion_start
        self.audio_start = audio_start
        self._motion = motion_parts
        self._audio = audio

    def __len__(self) -> int:
        return len(self.seq_ids)

    def motion(self, i: int) -> np.ndarray:
        """(frames, D) float32 motion view of window ``i``."""
        if self._motion is None:
            raise StoreError("these windows were opened without a motion view")
        a = int(self.motion_start[i])
        return stack_parts(self._motion, a, a + int(self.length[i]))

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
