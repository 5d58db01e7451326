"""Which frames each training window covers: N-measure windows and sliding windows in seconds.

A span is (sequence, first frame, frame count) on the sequence's own frame axis (frame 0 = the
sequence's first motion frame). Two families:

* **measures** — ``n_measures`` consecutive measures of the measures table (from ``segment``),
  frames ``[frame_start of the first, frame_stop of the last)``; windows start every
  ``hop_measures`` measures (default ``n_measures``: no overlap). A window whose measures are
  not consecutive numbers with touching frames (a gap in the table) is left out. With
  ``n_measures=1`` these are exactly the windows of :meth:`DanceStore.iter_measures`, in order.
* **beats** — ``n_beats`` consecutive beats of the beats table (``dancedata segment --tables
  measures,beats``) every ``hop_beats``: a beat spans from its frame to the next beat's frame,
  so a window of beats j … j+n−1 covers ``[frame of j, frame of j+n)`` and needs beat j+n in the
  table (the last beat of a sequence starts no window: its end is not in the sequence).
* **phrases** — ``n_phrases`` consecutive phrases of the phrases table (``--tables
  measures,phrases``, ``--phrase-measures``) every ``hop_phrases``, ``[frame_start of the
  first, frame_stop of the last)``, as measures.
* **seconds** — sliding windows of ``seconds`` (ChoreoGraph's 1 s / 4 s / 8 s units) every
  ``hop_seconds``: at a sequence's ``fps``, window ``k`` covers
  ``[round(k · hop_seconds · fps), that + round(seconds · fps))`` (round half up; the start is
  computed from ``k`` each time, so a fractional hop does not drift). Only whole windows are
  made: a tail shorter than a window is left out.

With an audio view, only frames the music covers count (``DanceStore.audio_frames``), as in
``iter_measures``: a sequence without music gives no windows.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any

import numpy as np

from dancedata.errors import InputError

if TYPE_CHECKING:
    from dancedata.read.sequence_reader import _SequenceReader


@dataclass(frozen=True)
class WindowSpans:
    """Spans of one dataset, one row per window (arrays of equal length)."""

    kind: str  # "measures", "beats", "phrases" or "seconds"
    seq_ids: tuple[str, ...]
    measure: np.ndarray  # (N,) int64 measure of the window's first frame; -1 for "seconds"
    frame_start: np.ndarray  # (N,) int64 first frame, on the sequence's frame axis
    length: np.ndarray  # (N,) int64 frames
    params: dict[str, Any] = field(default_factory=dict)  # how they were made (recorded)
    unit: np.ndarray | None = None  # (N,) int64 first beat / phrase number (beats, phrases)

    def __len__(self) -> int:
        return len(self.seq_ids)


UNIT_TABLES = {"beats": "beat", "phrases": "phrase"}
"""Window kinds cut from a unit table of ``segment``, with the table's number column."""


def _unit_rows(store: _SequenceReader, table: str, split: str | None, scheme: str) -> list[dict]:
    """Rows of ``table`` for the sequences of ``split``; StoreError naming the segment command
    that writes it when this version lacks it."""
    from dancedata.errors import StoreError

    if not store.has_table(table):
        raise StoreError(
            f"version {store.version} has no {table} table, which {table} windows are cut "
            f"from: run `dancedata segment {store.path} --tables measures,{table}`"
            + (" --phrase-measures 4 (or 8)" if table == "phrases" else ""),
            store.path,
        )
    wanted = set(store.seq_ids(split, scheme))
    return [r for r in store.table(table).to_pylist() if r["seq_id"] in wanted]


def unit_spans(
    store: _SequenceReader,
    kind: str,
    split: str | None,
    scheme: str,
    with_audio: bool,
    n_units: int = 1,
    hop_units: int | None = None,
) -> WindowSpans:
    """Spans of ``n_units`` consecutive beats or phrases (``kind`` "beats" or "phrases"; see
    the module docstring), every ``hop_units`` (default ``n_units``)."""
    if kind not in UNIT_TABLES:
        raise InputError(f"unit windows are {' or '.join(UNIT_TABLES)} (got {kind!r})")
    number = UNIT_TABLES[kind]
    if n_units < 1 or (hop_units is not None and hop_units < 1):
        raise InputError(f"n_{kind} and hop_{kind} must be ≥ 1 (got {n_units}, {hop_units})")
    rows = _unit_rows(store, kind, split, scheme)
    if kind == "beats":  # a beat spans to the next beat of its sequence
        by_seq: dict[str, list[dict]] = {}
        for r in rows:
            by_seq.setdefault(r["seq_id"], []).append(r)
        spans = []
        for seq_rows in by_seq.values():
            seq_rows.sort(key=lambda r: int(r["beat"]))
            for a, b in zip(seq_rows[:-1], seq_rows[1:], strict=True):
                if int(b["beat"]) == int(a["beat"]) + 1:
                    spans.append({**a, "frame_start": a["frame"], "frame_stop": b["frame"]})
        rows = spans
    else:
        rows = [{**r, "measure": r["measure_start"]} for r in rows]
    if with_audio:
        available = {s: _frames_available(store, s, True) for s in {r["seq_id"] for r in rows}}
        rows = [r for r in rows if r["frame_stop"] <= available[r["seq_id"]]]
    groups = measure_groups(
        [r["seq_id"] for r in rows],
        [int(r[number]) for r in rows],
        [int(r["frame_start"]) for r in rows],
        [int(r["frame_stop"]) for r in rows],
        n_units,
        hop_units,
    )
    first = [rows[g[0]] for g in groups]
    start = np.array([r["frame_start"] for r in first], dtype=np.int64)
    stop = np.array([rows[g[-1]]["frame_stop"] for g in groups], dtype=np.int64)
    return WindowSpans(
        kind=kind,
        seq_ids=tuple(r["seq_id"] for r in first),
        measure=np.array([r["measure"] for r in first], dtype=np.int64),
        frame_start=start,
        length=stop - start,
        params={f"n_{kind}": n_units, f"hop_{kind}": n_units if hop_units is None else hop_units},
        unit=np.array([r[number] for r in first], dtype=np.int64),
    )


def measure_groups(
    seq_ids: Sequence[str],
    measures: Sequence[int],
    starts: Sequence[int],
    stops: Sequence[int],
    n_measures: int = 1,
    hop_measures: int | None = None,
) -> list[tuple[int, ...]]:
    """Row indices of each ``n_measures`` window over measures-table rows (pure).

    Rows are grouped by sequence (in order of first appearance) and ordered by measure number
    within a sequence; a window starts at every ``hop_measures``-th row of a sequence and is
    kept when its rows are consecutive measure numbers whose frames touch."""
    hop = n_measures if hop_measures is None else hop_measures
    if n_measures < 1 or hop < 1:
        raise InputError(f"n_measures and hop_measures must be ≥ 1 (got {n_measures}, {hop})")
    by_seq: dict[str, list[int]] = {}
    for i, seq in enumerate(seq_ids):
        by_seq.setdefault(seq, []).append(i)
    out: list[tuple[int, ...]] = []
    for rows in by_seq.values():
        rows = sorted(rows, key=lambda i: measures[i])
        for k in range(0, len(rows) - n_measures + 1, hop):
            group = rows[k : k + n_measures]
            consecutive = all(
                measures[b] == measures[a] + 1 and starts[b] == stops[a]
                for a, b in zip(group[:-1], group[1:], strict=True)
            )
            if consecutive:
                out.append(tuple(group))
    return out


def sliding_starts(n_frames: int, window: int, hop: float) -> np.ndarray:
    """(K,) int64 first frames of every whole ``window``-frame window in ``n_frames`` frames,
    window ``k`` starting at ``floor(k · hop + 0.5)`` (``hop`` in frames, may be fractional)."""
    if window < 1 or hop <= 0:
        raise InputError(f"window must be ≥ 1 frame and hop > 0 (got {window}, {hop})")
    if n_frames < window:
        return np.zeros(0, dtype=np.int64)
    k_max = int(math.floor((n_frames - window) / hop)) + 2
    starts = np.floor(np.arange(k_max) * hop + 0.5).astype(np.int64)
    return starts[starts + window <= n_frames]


def _frames_available(store: _SequenceReader, seq_id: str, with_audio: bool) -> int:
    n = int(store.sequence(seq_id)["n_frames"])
    return min(n, store.audio_frames(seq_id)) if with_audio else n


def measure_spans(
    store: _SequenceReader,
    split: str | None,
    scheme: str,
    with_audio: bool,
    n_measures: int = 1,
    hop_measures: int | None = None,
) -> WindowSpans:
    """Spans of ``n_measures``-measure windows of ``split`` (see the module docstring)."""
    rows = store.measure_rows(split, scheme)
    if with_audio:
        available = {s: _frames_available(store, s, True) for s in {r["seq_id"] for r in rows}}
        rows = [r for r in rows if r["frame_stop"] <= available[r["seq_id"]]]
    groups = measure_groups(
        [r["seq_id"] for r in rows],
        [int(r["measure"]) for r in rows],
        [int(r["frame_start"]) for r in rows],
        [int(r["frame_stop"]) for r in rows],
        n_measures,
        hop_measures,
    )
    first = [rows[g[0]] for g in groups]
    last = [rows[g[-1]] for g in groups]
    start = np.array([r["frame_start"] for r in first], dtype=np.int64)
    stop = np.array([r["frame_stop"] for r in last], dtype=np.int64)
    return WindowSpans(
        kind="measures",
        seq_ids=tuple(r["seq_id"] for r in first),
        measure=np.array([r["measure"] for r in first], dtype=np.int64),
        frame_start=start,
        length=stop - start,
        params={
            "n_measures": n_measures,
            "hop_measures": n_measures if hop_measures is None else hop_measures,
        },
    )


def second_spans(
    store: _SequenceReader,
    split: str | None,
    scheme: str,
    with_audio: bool,
    seconds: float,
    hop_seconds: float | None = None,
) -> WindowSpans:
    """Spans of sliding ``seconds``-long windows every ``hop_seconds`` (default ``seconds``)."""
    hop_s = seconds if hop_seconds is None else hop_seconds
    if not seconds > 0 or not hop_s > 0:
        raise InputError(f"seconds and hop_seconds must be > 0 (got {seconds}, {hop_s})")
    seq_ids: list[str] = []
    starts: list[np.ndarray] = []
    lengths: list[np.ndarray] = []
    frames_per_fps: dict[float, int] = {}
    for seq_id in store.seq_ids(split, scheme):
        fps = float(store.sequence(seq_id)["fps"])
        window = int(math.floor(seconds * fps + 0.5))
        frames_per_fps[fps] = window
        s = sliding_starts(_frames_available(store, seq_id, with_audio), window, hop_s * fps)
        seq_ids += [seq_id] * len(s)
        starts.append(s)
        lengths.append(np.full(len(s), window, dtype=np.int64))
    return WindowSpans(
        kind="seconds",
        seq_ids=tuple(seq_ids),
        measure=np.full(len(seq_ids), -1, dtype=np.int64),
        frame_start=np.concatenate(starts) if starts else np.zeros(0, np.int64),
        length=np.concatenate(lengths) if lengths else np.zeros(0, np.int64),
        params={
            "seconds": seconds,
            "hop_seconds": hop_s,
            "window_frames_at_fps": {str(k): v for k, v in frames_per_fps.items()},
        },
    )
