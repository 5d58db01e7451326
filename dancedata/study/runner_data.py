"""What the experiment runner reads from a store: the measures of a split and their motion.

:func:`load_split` gathers the sequences of one split (genres excluded), their complete
measures, and their motion frames packed into compact arrays (trans m, Euler rad, quaternions
wxyz, axis-angle rad) so that every later step is one numpy expression over all measures.
:func:`select_keyframes` runs one keyframe strategy at one N over those measures, grouped by
measure length, with the batch functions of :mod:`dancedata.methods.keyframes`.
"""

from __future__ import annotations

from collections import Counter
from dataclasses import dataclass, field
from functools import cached_property
from typing import Any

import numpy as np

from dancedata.errors import InputError
from dancedata.methods.keyframes import KeyframeParams, even_batch
from dancedata.methods.keyframes_dp import dp_keyframes_batch
from dancedata.methods.keyframes_peaks import peak_keyframes_batch

DP_BATCH = 128  # measures per DP call: memory ≈ batch × L² × 8 B × 3


@dataclass
class SplitData:
    """The complete measures of one split and the motion frames they cover.

    Motion arrays are compact: row r is frame ``frames[r]`` of the store; ``seq_offset[s]``
    is the row of sequence s's first frame. Measures are in store order (sequence, measure).
    """

    label: str
    sequences: list[dict[str, Any]]
    seq_offset: np.ndarray  # (S,) compact row of each sequence's frame 0
    measure_seq: np.ndarray  # (M,) index into sequences
    measure: np.ndarray  # (M,) measure number within its sequence
    local_start: np.ndarray  # (M,) first frame within its sequence
    length: np.ndarray  # (M,) frames L
    audio_available: np.ndarray  # (M,) bool: audio covers the whole measure
    trans: np.ndarray  # (F, 3) float64 metres
    euler: np.ndarray  # (F, J, 3) float64 radians, the store's order
    quat: np.ndarray  # (F, J, 4) float64 wxyz
    axis_angle: np.ndarray | None  # (F, J, 3) float64 radians (FID ground truth)
    euler_order: Any
    genres_excluded: list[str] = field(default_factory=list)

    @property
    def start(self) -> np.ndarray:
        """(M,) compact row of each measure's first frame."""
        return self.seq_offset[self.measure_seq] + self.local_start

    @cached_property
    def x75(self) -> np.ndarray:
        """(F, 75) ``thesis_euler_75`` rows: trans (m) + Euler (rad) (built once)."""
        return np.concatenate([self.trans, self.euler.reshape(len(self.euler), -1)], axis=1)

    @property
    def seq_ids(self) -> list[str]:
        return [s["seq_id"] for s in self.sequences]


def _audio_frames(seq: dict[str, Any], music: dict[str, dict[str, Any]]) -> int:
    """Frames of the sequence that have audio (as ``DanceStore.audio_frames``)."""
    if seq.get("music_missing") or seq.get("music_id") not in music:
        return 0
    track = music[seq["music_id"]]
    available = track["frame_stop"] - track["frame_start"] - int(seq.get("audio_offset") or 0)
    return max(0, min(int(seq["n_frames"]), available))


def _split_sequences(reader: Any, scheme: str, splits: list[str], exclude: list[str]) -> list:
    sequences = reader.table("sequences").to_pylist()
    rows = reader.table("splits").to_pylist() if reader.has_table("splits") else []
    present = Counter((r["scheme"], r["split"]) for r in rows)
    if not any(s == scheme for s, _ in present):
        have = sorted({s for s, _ in present}) or "none"
        raise InputError(f"version {reader.version} has no split scheme {scheme!r} (have {have})")
    wanted = {r["seq_id"] for r in rows if r["scheme"] == scheme and r["split"] in splits}
    chosen = [s for s in sequences if s["seq_id"] in wanted and s.get("genre") not in exclude]
    if not chosen:
        have = ", ".join(f"{sp} {n}" for (sc, sp), n in sorted(present.items()) if sc == scheme)
        raise InputError(
            f"split {scheme}:{'+'.join(splits)} has no sequences in version {reader.version} "
            f"after excluding {exclude or 'nothing'} ({scheme} has: {have})"
        )
    return chosen


def _packed(array: Any, spans: list[tuple[int, int]]) -> np.ndarray:
    """Rows [a, b) of every span of a stored array, concatenated, float64."""
    total = int(array.shape[0])
    covered = sum(b - a for a, b in spans)
    if covered * 2 > total:  # most of the array: one read, then a gather
        whole = np.asarray(array[...])
        index = np.concatenate([np.arange(a, b) for a, b in spans])
        return whole[index].astype(np.float64)
    return np.concatenate([np.asarray(array[a:b]) for a, b in spans]).astype(np.float64)


def load_split(reader: Any, scheme: str, splits: list[str], exclude: list[str],
               need_axis_angle: bool = False) -> SplitData:  # fmt: skip
    """The measures of ``scheme:splits`` (minus ``exclude`` genres) and their motion."""
    if not reader.has_table("measures"):
        raise InputError(
            f"version {reader.version} has no measures table (run `dancedata segment` first)"
        )
    needed = ["motion/trans", "motion/euler", "motion/quat"]
    if need_axis_angle:
        needed.append("motion/axis_angle")
    missing = [n for n in needed if not reader.has_array(n)]
    if missing:
        raise InputError(
            f"version {reader.version} lacks {', '.join(missing)} (run `dancedata featurize`)"
        )
    sequences = _split_sequences(reader, scheme, splits, exclude)
    position = {s["seq_id"]: i for i, s in enumerate(sequences)}
    music = (
        {m["music_id"]: m for m in reader.table("music").to_pylist()}
        if reader.has_table("music")
        else {}
    )
    rows = [r for r in reader.table("measures").to_pylist() if r["seq_id"] in position]
    measure_seq = np.array([position[r["seq_id"]] for r in rows], dtype=np.int64)
    local = np.array([r["frame_start"] for r in rows], dtype=np.int64)
    stop = np.array([r["frame_stop"] for r in rows], dtype=np.int64)
    covered = np.array([_audio_frames(s, music) for s in sequences], dtype=np.int64)
    spans = [(int(s["frame_start"]), int(s["frame_stop"])) for s in sequences]
    lengths = np.array([b - a for a, b in spans], dtype=np.int64)
    euler_array = reader.array("motion/euler")
    euler = _packed(euler_array, spans)
    return SplitData(
        label=f"{scheme}:{'+'.join(splits)}",
        sequences=sequences,
        seq_offset=np.cumsum(lengths) - lengths,
        measure_seq=measure_seq,
        measure=np.array([r["measure"] for r in rows], dtype=np.int64),
        local_start=local,
        length=stop - local,
        audio_available=stop <= covered[measure_seq] if rows else np.zeros(0, bool),
        trans=_packed(reader.array("motion/trans"), spans),
        euler=euler,
        quat=_packed(reader.array("motion/quat"), spans),
        axis_angle=_packed(reader.array("motion/axis_angle"), spans) if need_axis_angle else None,
        euler_order=euler_array.attrs.get("order", "XYZ"),
        genres_excluded=list(exclude),
    )


def require_strategy_inputs(reader: Any, strategy: str, params: KeyframeParams) -> str | None:
    """None when the version holds what ``strategy`` reads, else the one-line reason."""
    if strategy in ("even", "dp"):
        return None
    if strategy == "peaks:onset":
        needed = ["audio/onset_env"]
        hint = "featurize a store with music"
    elif strategy == "peaks:stems":
        needed = [f"audio/stems/{s}/onset_env" for s, w in params.stem_weights.items() if w]
        hint = "featurize with --stems offline|openunmix"
    else:
        needed = ["audio/nmfd_drums"]
        hint = "featurize with the nmfd audio family"
    missing = [n for n in needed if not reader.has_array(n)]
    if missing:
        return f"no {', '.join(missing)} in version {reader.version} ({hint})"
    return None


def _continuous(data: SplitData) -> np.ndarray:
    from dancedata.compute.euler_continuity import euler_continuous

    out = data.euler.copy()
    orders = (
        [data.euler_order] * out.shape[1]
        if isinstance(data.euler_order, str)
        else list(data.euler_order)
    )
    ends = np.append(data.seq_offset[1:], len(out))
    for a, b in zip(data.seq_offset.tolist(), ends.tolist(), strict=True):
        for one in set(orders):
            joints = [j for j, o in enumerate(orders) if o == one]
            out[a:b, joints] = euler_continuous(out[a:b, joints], one)
    return out


def select_keyframes(
    data: SplitData,
    strategy: str,
    n: int,
    params: KeyframeParams,
    store: Any = None,
    rows: np.ndarray | None = None,
) -> tuple[np.ndarray, np.ndarray]:
    """Keyframes of ``strategy`` with N per measure over ``rows`` (indices into the measures;
    default all that can hold N). Returns (rows, (M', K) local keyframe indices), K = N or
    N + 2 (``n_counts_edges = False``). ``store`` (a DanceStore) is read for audio curves."""
    total = params.total_keyframes(n)
    if rows is None:
        rows = np.flatnonzero(data.length >= total)
    out = np.zeros((rows.size, total), dtype=np.int64)
    curves = None
    if strategy.startswith("peaks:"):
        from dancedata.study.keyframes import CurveSource

        curves = CurveSource(store, data.sequences, strategy, params)
    x75 = None
    if strategy == "dp":
        euler = _continuous(data) if params.euler_branch == "continuous" else data.euler
        x75 = np.concatenate([data.trans, euler.reshape(len(euler), -1)], axis=1)
    lengths = data.length[rows]
    for length in np.unique(lengths).tolist():
        where = np.flatnonzero(lengths == length)
        group = rows[where]
        if strategy == "even":
            idx = even_batch(group.size, length, total)[0]
        elif strategy == "dp":
            parts = []
            for begin in range(0, group.size, DP_BATCH):
                part = group[begin : begin + DP_BATCH]
                x = x75[data.start[part][:, None] + np.arange(length)]
                parts.append(dp_keyframes_batch(x, [total], params.dp_distance, params.combine)
                             [total][0])  # fmt: skip
            idx = np.concatenate(parts)
        else:
            assert curves is not None
            values, peaks = curves.gather(data.measure_seq[group], data.local_start[group], length)
            idx = peak_keyframes_batch(values, total, params.guard, params.fill, peaks)[0]
        out[where] = idx
    return rows, out
