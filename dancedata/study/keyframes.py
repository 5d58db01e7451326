"""``dancedata keyframes``: the keyframes table of every measure, as a new version.

Reads the measures table, the 75-d Euler rows (``motion/trans`` + ``motion/euler``) and the
audio curves of a version, runs the requested strategies at every requested N with the pure
functions of :mod:`dancedata.methods.keyframes`, and writes ``keyframes.parquet`` (one row
per keyframe, docs/EXPERIMENTS.md §2.5) into a new version. Measures are grouped by length and each
group is selected in one batch; the only per-sequence loop assembles the audio curves.

The strategies, N values and every [CHOICE] parameter are the command's config: recorded in the
manifest and hashed into the fingerprint with the data the result derives from (the ingest,
featurize and segment stages), so running it again with the same settings writes nothing.
Each (strategy, N) has its own ``run_id`` in the table: a hash of the strategy, N, the
parameters that strategy uses, and the same data stages.
"""

from __future__ import annotations

import time
from collections import defaultdict
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from dancedata._version import __version__
from dancedata.errors import InputError, StoreError
from dancedata.methods.keyframes import (
    STRATEGIES,
    KeyframeParams,
    canonical_strategy,
    even_batch,
)
from dancedata.methods.keyframes_dp import dp_keyframes_batch
from dancedata.methods.keyframes_peaks import DP, KEYFRAME_SOURCES, peak_keyframes_batch
from dancedata.store.backend import StoreBackend
from dancedata.store.checksums import fingerprint
from dancedata.store.command_result import CommandResult
from dancedata.store.reader import _VersionReader
from dancedata.store.version_step import DerivedVersion, derive_version

DATA_STAGES = ("ingest", "featurize", "segment")
# Measures per DP batch: bounds memory to about batch × L² × 8 bytes × 3 (L = 180: 100 MB).
DP_BATCH = 128


@dataclass
class KeyframesOptions:
    strategies: list[str] = field(default_factory=lambda: ["even"])
    n_keyframes: list[int] = field(default_factory=lambda: [3, 5, 9])
    params: KeyframeParams = field(default_factory=KeyframeParams)
    split: str | None = None
    scheme: str = "crossmodal"
    exclude_genres: list[str] = field(default_factory=list)
    version: str | None = None
    wait_for_lock: bool = False

    def __post_init__(self) -> None:
        seen: list[str] = []
        for name in self.strategies:
            strategy = canonical_strategy(name)
            if strategy not in seen:
                seen.append(strategy)
        if not seen:
            raise InputError("no keyframe strategy given")
        self.strategies = [s for s in STRATEGIES if s in seen]
        if not self.n_keyframes:
            raise InputError("no keyframe count N given")
        bad = [n for n in self.n_keyframes if n < (2 if self.params.n_counts_edges else 0)]
        if bad:
            raise InputError(f"keyframe counts {bad} are too small (N counts the first and last)")
        self.n_keyframes = sorted(set(int(n) for n in self.n_keyframes))

    def config(self, context: dict[str, Any]) -> dict[str, Any]:
        return {
            "strategies": self.strategies,
            "n_keyframes": self.n_keyframes,
            "params": self.params.as_dict(),
            "split": None if self.split is None else {"scheme": self.scheme, "split": self.split},
            "exclude_genres": sorted(self.exclude_genres),
            **context,
        }


@dataclass
class MeasureSet:
    """The measures to select keyframes for, as parallel arrays."""

    seq_id: list[str]
    measure: np.ndarray  # measure number within its sequence
    local_start: np.ndarray  # first frame within the sequence
    length: np.ndarray  # L
    motion_start: np.ndarray  # first frame in the store's motion arrays
    audio_available: np.ndarray  # bool: the sequence's audio covers the whole measure
    seq_index: np.ndarray  # row of the sequence in ``sequences``

    def groups(self, rows: np.ndarray) -> dict[int, np.ndarray]:
        """``rows`` (indices into this set) grouped by measure length."""
        out: dict[int, np.ndarray] = {}
        for length in np.unique(self.length[rows]).tolist():
            out[int(length)] = rows[self.length[rows] == length]
        return out


def _measure_set(reader: _VersionReader, options: KeyframesOptions) -> tuple[MeasureSet, list]:
    if not reader.has_table("measures"):
        raise InputError(
            f"version {reader.version} has no measures table (run `dancedata segment` first)"
        )
    sequences = reader.table("sequences").to_pylist()
    by_id = {s["seq_id"]: i for i, s in enumerate(sequences)}
    wanted = set(by_id)
    if options.split is not None:
        splits = reader.table("splits").to_pylist() if reader.has_table("splits") else []
        if not any(r["scheme"] == options.scheme for r in splits):
            raise InputError(f"no split scheme {options.scheme!r} in version {reader.version}")
        wanted = {
            r["seq_id"]
            for r in splits
            if r["scheme"] == options.scheme and r["split"] == options.split
        }
    excluded = set(options.exclude_genres)
    rows = [
        r
        for r in reader.table("measures").to_pylist()
        if r["seq_id"] in wanted and sequences[by_id[r["seq_id"]]].get("genre") not in excluded
    ]
    music = (
        {m["music_id"]: m for m in reader.table("music").to_pylist()}
        if reader.has_table("music")
        else {}
    )
    audio_frames = [_audio_frames(s, music) for s in sequences]
    seq_index = np.array([by_id[r["seq_id"]] for r in rows], dtype=np.int64)
    local = np.array([r["frame_start"] for r in rows], dtype=np.int64)
    stop = np.array([r["frame_stop"] for r in rows], dtype=np.int64)
    seq_start = np.array([s["frame_start"] for s in sequences], dtype=np.int64)
    covered = np.array(audio_frames, dtype=np.int64)
    return (
        MeasureSet(
            seq_id=[r["seq_id"] for r in rows],
            measure=np.array([r["measure"] for r in rows], dtype=np.int64),
            local_start=local,
            length=stop - local,
            motion_start=seq_start[seq_index] + local,
            audio_available=stop <= covered[seq_index],
            seq_index=seq_index,
        ),
        sequences,
    )


def _audio_frames(seq: dict[str, Any], music: dict[str, dict[str, Any]]) -> int:
    """Frames of the sequence that have audio (as :meth:`DanceStore.audio_frames`)."""
    if seq.get("music_missing") or seq.get("music_id") not in music:
        return 0
    track = music[seq["music_id"]]
    available = track["frame_stop"] - track["frame_start"] - int(seq["audio_offset"])
    return max(0, min(int(seq["n_frames"]), available))


class CurveSource:
    """The 1-d curve of a peak strategy for every sequence, concatenated, so that the curves of
    a batch of measures are one fancy-index gather."""

    def __init__(self, store: Any, sequences: list[dict[str, Any]], strategy: str,
                 params: KeyframeParams) -> None:  # fmt: skip
        self.offsets = np.zeros(len(sequences), dtype=np.int64)
        pieces: list[np.ndarray] = []
        peak_pieces: list[np.ndarray] = []
        position = 0
        use_detect = strategy == "peaks:onset" and params.peak_source == "onset_detect"
        for i, seq in enumerate(sequences):
            self.offsets[i] = position
            seq_id = seq["seq_id"]
            if store.audio_frames(seq_id) == 0:
                continue
            curve = np.asarray(_sequence_curve(store, seq_id, strategy, params), np.float64)
            if not np.isfinite(curve).all():
                first = int(np.flatnonzero(~np.isfinite(curve))[0])
                raise InputError(
                    f"{strategy}: the curve of {seq_id} holds NaN or Inf (first at frame {first})"
                )
            pieces.append(curve)
            if use_detect:
                peak_pieces.append(np.asarray(store.audio(seq_id, "onset_peaks")) > 0)
            position += curve.shape[0]
        self.values = np.concatenate(pieces) if pieces else np.zeros(0)
        self.peaks = np.concatenate(peak_pieces) if use_detect and peak_pieces else None

    def gather(self, seq_index: np.ndarray, local_start: np.ndarray, length: int) -> tuple:
        idx = (self.offsets[seq_index] + local_start)[:, None] + np.arange(length)
        peaks = None if self.peaks is None else self.peaks[idx]
        return self.values[idx], peaks


def _sequence_curve(store: Any, seq_id: str, strategy: str, params: KeyframeParams) -> np.ndarray:
    if strategy == "peaks:onset":
        return store.audio(seq_id, "onset_env")
    if strategy == "peaks:stems":
        return store.weighted_stem_onsets(seq_id, params.stem_weights, params.normalize)
    return store.weighted_nmfd(seq_id, params.nmfd_weights, params.normalize)


def _require_arrays(reader: _VersionReader, strategy: str, params: KeyframeParams) -> None:
    """One clear line when the version lacks what ``strategy`` reads."""
    if strategy == "even":
        return
    if strategy == "dp":
        needed = ["motion/trans", "motion/euler"]
        hint = "run `dancedata featurize` (euler representation)"
    elif strategy == "peaks:onset":
        needed = ["audio/onset_env"]
        if params.peak_source == "onset_detect":
            needed.append("audio/onset_peaks")
        hint = "run `dancedata featurize` on a store with music"
    elif strategy == "peaks:stems":
        needed = [
            f"audio/stems/{stem}/onset_env"
            for stem, weight in params.stem_weights.items()
            if float(weight) != 0.0
        ]
        hint = "run `dancedata featurize --stems offline|openunmix`"
    else:
        needed = ["audio/nmfd_drums"]
        hint = "run `dancedata featurize` with the nmfd audio family"
    missing = [name for name in needed if not reader.has_array(name)]
    if missing:
        raise InputError(
            f"keyframe strategy {strategy} needs {', '.join(missing)}, which version "
            f"{reader.version} lacks ({hint})"
        )


class EulerRows:
    """The measures' 75-d Euler rows (trans m + 24×3 Euler rad), read once, gathered per batch;
    with ``euler_branch = continuous`` each sequence's curves are made continuous first."""

    def __init__(self, reader: _VersionReader, sequences: list[dict[str, Any]],
                 params: KeyframeParams, order: Any) -> None:  # fmt: skip
        self.trans = np.asarray(reader.array("motion/trans")[...], dtype=np.float64)
        euler = np.asarray(reader.array("motion/euler")[...])
        bad = ~np.isfinite(euler).reshape(euler.shape[0], -1).all(axis=1)
        bad |= ~np.isfinite(self.trans).all(axis=1)
        if bad.any():
            frame = int(np.flatnonzero(bad)[0])
            seq = next(s for s in sequences if s["frame_start"] <= frame < s["frame_stop"])
            raise InputError(
                f"dp: motion of {seq['seq_id']} holds NaN or Inf "
                f"(first at frame {frame - int(seq['frame_start'])})"
            )
        if params.euler_branch == "continuous":
            euler = _continuous_euler(euler, sequences, order)
        self.euler = euler.reshape(euler.shape[0], -1)

    def gather(self, motion_start: np.ndarray, length: int) -> np.ndarray:
        idx = motion_start[:, None] + np.arange(length)
        return np.concatenate(
            [self.trans[idx], self.euler[idx].astype(np.float64)], axis=2
        )  # (M, L, 75)


def _continuous_euler(euler: np.ndarray, sequences: list[dict[str, Any]], order: Any) -> np.ndarray:
    from dancedata.compute.euler_continuity import euler_continuous

    out = euler.astype(np.float64)
    orders = [order] * euler.shape[1] if isinstance(order, str) else list(order)
    for seq in sequences:
        a, b = int(seq["frame_start"]), int(seq["frame_stop"])
        for one in set(orders):
            joints = [j for j, o in enumerate(orders) if o == one]
            out[a:b, joints] = euler_continuous(out[a:b, joints], one)
    return out


@dataclass
class Selection:
    """The keyframes of one (strategy, N) over a set of measures."""

    rows: np.ndarray  # indices into the MeasureSet, (M,)
    indices: np.ndarray  # (M, K) local frames
    sources: np.ndarray  # (M, K) int8 codes
    scores: np.ndarray  # (M, K)


def _select(
    strategy: str,
    measures: MeasureSet,
    rows: np.ndarray,
    options: KeyframesOptions,
    curves: CurveSource | None,
    euler_rows: EulerRows | None,
) -> dict[int, list[Selection]]:
    """Every requested N of one strategy over ``rows``, batched by measure length."""
    params = options.params
    totals_all = {n: params.total_keyframes(n) for n in options.n_keyframes}
    out: dict[int, list[Selection]] = defaultdict(list)
    for length, group in measures.groups(rows).items():
        # N values this length can hold (shorter measures were reported as skipped)
        totals = {n: t for n, t in totals_all.items() if t <= length}
        if not totals:
            continue
        if strategy == "even":
            for n, total in totals.items():
                idx, src, score = even_batch(group.size, length, total)
                out[n].append(Selection(group, idx, src, score))
        elif strategy == "dp":
            assert euler_rows is not None
            for start in range(0, group.size, DP_BATCH):
                part = group[start : start + DP_BATCH]
                x = euler_rows.gather(measures.motion_start[part], length)
                found = dp_keyframes_batch(
                    x, sorted(set(totals.values())), params.dp_distance, params.combine
                )
                for n, total in totals.items():
                    idx, _cost, score = found[total]
                    src = np.full(idx.shape, DP, dtype=np.int8)
                    src[:, [0, -1]] = 0
                    out[n].append(Selection(part, idx, src, score))
        else:
            assert curves is not None
            values, peaks = curves.gather(
                measures.seq_index[group], measures.local_start[group], length
            )
            for n, total in totals.items():
                idx, src, score = peak_keyframes_batch(
                    values, total, params.guard, params.fill, peaks
                )
                out[n].append(Selection(group, idx, src, score))
    return out


def _run_id(strategy: str, n: int, params: KeyframeParams, data: dict[str, Any]) -> str:
    config = {"strategy": strategy, "n_keyframes": n, "params": params.for_strategy(strategy)}
    return fingerprint("keyframes-run", config, [str(v) for v in data.values()], __version__)[:16]


def _table(selections: list[tuple[str, int, str, list[Selection]]], measures: MeasureSet) -> Any:
    """The keyframes table (docs/EXPERIMENTS.md §2.5) from every selection, column by column."""
    import pyarrow as pa

    columns: dict[str, list[np.ndarray]] = defaultdict(list)
    run_ids: list[np.ndarray] = []
    strategies: list[np.ndarray] = []
    seq_rows: list[np.ndarray] = []
    for run_id, n, strategy, parts in selections:
        for sel in parts:
            m, k = sel.indices.shape
            rows = np.repeat(sel.rows, k)
            seq_rows.append(rows)
            run_ids.append(np.full(rows.size, run_id, dtype=object))
            strategies.append(np.full(rows.size, strategy, dtype=object))
            columns["measure"].append(measures.measure[rows])
            columns["n_keyframes"].append(np.full(rows.size, n))
            columns["k"].append(np.tile(np.arange(k), m))
            columns["frame"].append(sel.indices.reshape(-1))
            columns["frame_in_sequence"].append(
                (measures.local_start[sel.rows][:, None] + sel.indices).reshape(-1)
            )
            columns["source"].append(sel.sources.reshape(-1))
            columns["score"].append(sel.scores.reshape(-1))

    def cat(name: str) -> np.ndarray:
        return np.concatenate(columns[name]) if columns[name] else np.zeros(0)

    rows = np.concatenate(seq_rows) if seq_rows else np.zeros(0, dtype=np.int64)
    seq_ids = np.asarray(measures.seq_id, dtype=object)[rows] if rows.size else []
    names = np.asarray(KEYFRAME_SOURCES, dtype=object)
    table = pa.table(
        {
            "run_id": pa.array(np.concatenate(run_ids) if run_ids else [], pa.string()),
            "seq_id": pa.array(seq_ids, pa.string()),
            "measure": pa.array(cat("measure").astype(np.int32), pa.int32()),
            "strategy": pa.array(np.concatenate(strategies) if strategies else [], pa.string()),
            "n_keyframes": pa.array(cat("n_keyframes").astype(np.int16), pa.int16()),
            "k": pa.array(cat("k").astype(np.int16), pa.int16()),
            "frame": pa.array(cat("frame").astype(np.int32), pa.int32()),
            "frame_in_sequence": pa.array(cat("frame_in_sequence").astype(np.int32), pa.int32()),
            "source": pa.array(names[cat("source").astype(np.int64)], pa.string()),
            "score": pa.array(cat("score").astype(np.float32), pa.float32()),
        }
    )
    return table


def keyframes(store: str | Path | StoreBackend, options: KeyframesOptions) -> CommandResult:
    """Select keyframes for every measure and write the keyframes table as a new version
    derived from ``options.version`` (default: the latest, as it is once the lock is held)."""
    # Parent, fingerprint and the "already done" check are read under the store lock, as in
    # segment: a run that waited behind another writer derives from that writer's result.
    with derive_version(store, "keyframes", options.version, options.wait_for_lock) as step:
        return _keyframes_step(step, options)


def _keyframes_step(step: DerivedVersion, options: KeyframesOptions) -> CommandResult:
    from dancedata.read.loader import DanceStore

    reader = step.reader
    stages = reader.manifest.get("stages") or {}
    data = {stage: stages.get(stage) for stage in DATA_STAGES}
    if data["ingest"] is None:
        data["ingest"] = reader.manifest["fingerprint"]
    for strategy in options.strategies:
        _require_arrays(reader, strategy, options.params)
    needs_euler = "dp" in options.strategies
    euler_order = reader.array("motion/euler").attrs.get("order") if needs_euler else None
    if needs_euler and options.params.euler_branch == "continuous" and euler_order is None:
        raise InputError("motion/euler has no 'order' attribute: cannot make it continuous")
    stem_backend = (
        reader.group_attrs("audio/stems").get("backend")
        if "peaks:stems" in options.strategies
        else None
    )
    run_ids = {
        f"{s}@{n}": _run_id(s, n, options.params, data)
        for s in options.strategies
        for n in options.n_keyframes
    }
    context = {
        "euler_order": euler_order,
        "stem_backend": stem_backend,
        "data_stages": data,
        "run_ids": run_ids,
        "sources": list(KEYFRAME_SOURCES),
        "score": "curve value at peak/fill keyframes; segment error e(prev, k) at dp "
        "keyframes k ≥ 1 (from the DP's error table); NaN otherwise",
    }
    config = options.config(context)
    fp = step.fingerprint(config, [str(v) for v in data.values()])
    done = step.already_done(fp)
    if done is not None:
        return done

    measures, sequences = _measure_set(reader, options)
    loader = DanceStore(reader)  # the step's open parent, not a second open
    everything = np.arange(len(measures.seq_id))
    selections: list[tuple[str, int, str, list[Selection]]] = []
    skipped: dict[tuple[str, str], str] = {}
    per_run: dict[str, int] = {}
    counts: dict[str, Any] = {"measures": int(everything.size), "seconds": {}, "runs": per_run}
    totals = {n: options.params.total_keyframes(n) for n in options.n_keyframes}
    euler_rows = None
    for strategy in options.strategies:
        began = time.perf_counter()
        smallest = min(totals.values())
        rows = everything[measures.length >= smallest]
        for i in everything[measures.length < max(totals.values())].tolist():
            length = int(measures.length[i])
            too_many = [n for n, t in totals.items() if t > length]
            skipped[(measures.seq_id[i], strategy)] = (
                f"{strategy}: measure {int(measures.measure[i])} has {length} frames, too few "
                f"for N = {', '.join(map(str, too_many))}"
            )
        curves = None
        if strategy.startswith("peaks:"):
            no_audio = rows[~measures.audio_available[rows]]
            for i in no_audio.tolist():
                key = (measures.seq_id[i], strategy)
                skipped.setdefault(key, f"{strategy}: no audio under measure(s) of this sequence")
            rows = rows[measures.audio_available[rows]]
            curves = CurveSource(loader, sequences, strategy, options.params)
        if strategy == "dp" and euler_rows is None:
            euler_rows = EulerRows(reader, sequences, options.params, euler_order)
        found = _select(strategy, measures, rows, options, curves, euler_rows)
        for n in options.n_keyframes:
            parts = found.get(n, [])
            selections.append((run_ids[f"{strategy}@{n}"], n, strategy, parts))
            per_run[f"{strategy}@{n}"] = int(sum(p.rows.size for p in parts))
        counts["seconds"][strategy] = round(time.perf_counter() - began, 3)
        counts[f"measures_{strategy}"] = int(rows.size)
    table = _table(selections, measures)
    if table.num_rows == 0:
        why = next(iter(skipped.values()), "the version has no measures")
        raise InputError(f"no keyframes to write: every measure was left out ({why})")
    counts["rows"] = table.num_rows
    counts["units"] = 1
    counts["resumed_units"] = 0
    with step.writer(config, fp) as version:
        for (seq_id, _strategy), reason in sorted(skipped.items()):
            version.skip(seq_id, reason)
        version.write_table("keyframes", table)
        name = version.commit(counts=counts)
    return CommandResult(version=name, created=True, counts=counts, skipped=list(version.skipped))


def read_keyframes(store: str | Path, version: str | None = None) -> Any:
    """The keyframes table of a version (pyarrow Table); StoreError when it has none."""
    return _keyframes_table(_VersionReader(store, version))


def _keyframes_table(reader: _VersionReader) -> Any:
    """The keyframes table of the open version ``reader``; StoreError when it has none."""
    if not reader.has_table("keyframes"):
        raise StoreError(
            f"version {reader.version} has no keyframes table (run `dancedata keyframes`)"
        )
    return reader.table("keyframes")


@dataclass(frozen=True)
class KeyframeRun:
    """The keyframes of one run (one strategy and N) of a version, per measure, ready for the
    in-betweeners: ``segments()`` is their :class:`~dancedata.methods.inbetween.SegmentMap`
    over the store's frame-concatenated motion arrays."""

    run_id: str
    strategy: str
    n_keyframes: int
    seq_id: list[str]
    measure: np.ndarray  # (M,)
    motion_start: np.ndarray  # (M,) global frame of each measure's local frame 0
    length: np.ndarray  # (M,) L
    keyframes: np.ndarray  # (M, K) local frames

    def segments(self) -> Any:
        from dancedata.methods.inbetween import segment_map

        return segment_map(self.motion_start, self.length, self.keyframes)


def keyframe_run(
    store: str | Path,
    run_id: str | None = None,
    *,
    strategy: str | None = None,
    n_keyframes: int | None = None,
    version: str | None = None,
) -> KeyframeRun:
    """One run of a version's keyframes table, by ``run_id`` or by ``strategy`` and N.

    Measures come in the table's order (sequence, measure); their global frames and lengths are
    taken from the sequences and measures tables of the same version.
    """
    reader = _VersionReader(store, version)
    table = _keyframes_table(reader)  # the same open version, not a second open
    runs = reader.manifest.get("config", {}).get("run_ids", {})
    if run_id is None:
        if strategy is None or n_keyframes is None:
            raise InputError("name a keyframe run by run_id, or by strategy and N")
        key = f"{canonical_strategy(strategy)}@{int(n_keyframes)}"
        if key not in runs:
            raise InputError(
                f"version {reader.version} has no keyframes run {key} (has {sorted(runs)})"
            )
        run_id = runs[key]
    columns = table.to_pydict()
    chosen = np.flatnonzero(np.asarray(columns["run_id"], dtype=object) == run_id)
    if chosen.size == 0:
        raise InputError(f"version {reader.version} has no keyframes run {run_id!r}")
    seq_ids = np.asarray(columns["seq_id"], dtype=object)[chosen]
    measure = np.asarray(columns["measure"], dtype=np.int64)[chosen]
    k = np.asarray(columns["k"], dtype=np.int64)[chosen]
    frame = np.asarray(columns["frame"], dtype=np.int64)[chosen]
    per_measure = int(k.max()) + 1
    if (
        chosen.size % per_measure
        or not (k.reshape(-1, per_measure) == np.arange(per_measure)).all()
    ):
        raise StoreError(
            f"keyframes run {run_id} of version {reader.version} is not whole measures"
        )
    firsts = np.arange(0, chosen.size, per_measure)
    sequences = {s["seq_id"]: s for s in reader.table("sequences").to_pylist()}
    bounds = {
        (r["seq_id"], r["measure"]): (r["frame_start"], r["frame_stop"])
        for r in reader.table("measures").to_pylist()
    }
    seq_list = [str(s) for s in seq_ids[firsts]]
    local = np.array([bounds[(s, int(m))] for s, m in zip(seq_list, measure[firsts], strict=True)])
    starts = np.array([sequences[s]["frame_start"] for s in seq_list], dtype=np.int64)
    return KeyframeRun(
        run_id=run_id,
        strategy=str(columns["strategy"][chosen[0]]),
        n_keyframes=int(columns["n_keyframes"][chosen[0]]),
        seq_id=seq_list,
        measure=measure[firsts],
        motion_start=starts + local[:, 0],
        length=local[:, 1] - local[:, 0],
        keyframes=frame.reshape(-1, per_measure),
    )
