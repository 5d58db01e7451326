"""The measures of a split as view windows: records one by one, or fast random access.

:func:`iter_measures` yields a :class:`MeasureWindow` per measure (``DanceStore.iter_measures``);
:func:`measure_windows` does the table lookups once and hands :class:`dancedata.read.windows
.MeasureWindows` plain arrays (``DanceStore.measure_windows``). With an audio view, both leave
out measures the audio does not fully cover.
"""

from __future__ import annotations

from collections.abc import Iterator
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

from dancedata.read.views.assemble import sequence_view, view_parts
from dancedata.read.views.layouts import ViewSpec, check_view_names
from dancedata.read.windows import MeasureWindows

if TYPE_CHECKING:
    from dancedata.read.sequence_reader import _SequenceReader


@dataclass(frozen=True)
class MeasureWindow:
    """One measure of one sequence: frames [frame_start, frame_stop) of the sequence."""

    seq_id: str
    measure: int
    frame_start: int
    frame_stop: int
    motion: np.ndarray | None
    audio: np.ndarray | None
    genre_onehot: np.ndarray


def measure_windows(
    store: _SequenceReader,
    split: str | None = None,
    scheme: str = "crossmodal",
    motion: ViewSpec | None = "fact_motion_225",
    audio: ViewSpec | None = "fact_audio_35",
) -> MeasureWindows:
    """The measures of ``split`` as :class:`MeasureWindows` over the ``motion`` and ``audio``
    views (either may be None): each window's global frame offsets and the views' arrays."""
    check_view_names(motion, audio)
    rows = store.measure_rows(split, scheme)
    seq_start: dict[str, int] = {}
    audio_start: dict[str, int] = {}
    audio_frames: dict[str, int] = {}
    for seq_id in {r["seq_id"] for r in rows}:
        seq_start[seq_id] = int(store.sequence(seq_id)["frame_start"])
        audio_frames[seq_id] = store.audio_frames(seq_id) if audio else 0
        audio_start[seq_id] = store.audio_start(seq_id) if audio else 0
    if audio:  # measures not fully covered by audio are left out, as iter_measures does
        rows = [r for r in rows if r["frame_stop"] <= audio_frames[r["seq_id"]]]
    seq_ids = [r["seq_id"] for r in rows]
    starts = np.array([r["frame_start"] for r in rows], dtype=np.int64)
    motion_parts = view_parts(store, motion) if motion else None
    audio_rows = None
    if audio:  # audio views are narrow (≤ 88 floats per frame): assemble the whole view once
        audio_rows = np.concatenate([p for p in view_parts(store, audio) if p is not None], axis=1)
    audio_offsets = np.array([audio_start[s] for s in seq_ids], dtype=np.int64)
    return MeasureWindows(
        seq_ids=seq_ids,
        measure=np.array([r["measure"] for r in rows], dtype=np.int64),
        length=np.array([r["frame_stop"] for r in rows], dtype=np.int64) - starts,
        motion_start=np.array([seq_start[s] for s in seq_ids], dtype=np.int64) + starts,
        audio_start=audio_offsets + starts,
        motion_parts=motion_parts,
        audio=audio_rows,
    )


def iter_measures(
    store: _SequenceReader,
    split: str | None = None,
    scheme: str = "crossmodal",
    motion: ViewSpec | None = "fact_motion_225",
    audio: ViewSpec | None = "fact_audio_35",
) -> Iterator[MeasureWindow]:
    """Every measure of the sequences in ``split``, with the chosen motion and audio views
    sliced to the measure. With an audio view, measures not fully covered by audio are left
    out."""
    views: dict[str, np.ndarray] = {}
    for row in store.measure_rows(split, scheme):
        seq_id = row["seq_id"]
        if seq_id not in views:
            views.clear()
            views[seq_id] = np.empty(0)
            if motion:
                views["motion"] = sequence_view(store, seq_id, motion)
            if audio:
                if store.audio_frames(seq_id) == 0:
                    continue
                views["audio"] = sequence_view(store, seq_id, audio)
        if audio and ("audio" not in views or views["audio"].shape[0] < row["frame_stop"]):
            continue
        s0, s1 = row["frame_start"], row["frame_stop"]
        yield MeasureWindow(
            seq_id=seq_id,
            measure=row["measure"],
            frame_start=s0,
            frame_stop=s1,
            motion=views["motion"][s0:s1] if motion else None,
            audio=views["audio"][s0:s1] if audio else None,
            genre_onehot=store.genre_onehot(seq_id),
        )
