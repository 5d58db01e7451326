"""``dancedata stats``: per-array normalisation statistics of a training split, as a new version.

For each requested array (``motion/quat``, ``audio/mfcc``, any frame-indexed float array), the
mean and standard deviation of every column over the frames of one split's sequences, computed
once and stored in the version's ``normalization`` table (one row per array and column), so
every training run normalises with the same numbers and an export can undo it. Motion rows are
the split's sequence frames; audio rows are each split sequence's aligned audio frames, a song's
row counted once per sequence that uses it (what training windows see).

Reading is in blocks of whole chunks with float64 accumulation (``compute.normalization``), so
memory stays at a block whatever the store's size.
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from dancedata.compute.normalization import STD_FLOOR, Moments
from dancedata.errors import InputError
from dancedata.read.sequence_reader import _SequenceReader
from dancedata.store.backend import StoreBackend
from dancedata.store.command_result import CommandResult
from dancedata.store.reader import _VersionReader
from dancedata.store.version_step import DerivedVersion, derive_version

__all__ = ["DEFAULT_ARRAYS", "StatsOptions", "stats"]

DATA_STAGES = ("ingest", "featurize")
# Used when no --arrays are given: those of these the version has.
DEFAULT_ARRAYS = (
    "motion/trans",
    "motion/axis_angle",
    "motion/rotmat",
    "motion/euler",
    "motion/quat",
    "motion/rot6d",
    "motion/rot6d_rows",
    "motion/positions",
    "audio/onset_env",
    "audio/mfcc",
    "audio/chroma_cens",
)
BLOCK_ROWS = 65536  # rows per read, rounded to whole chunks


@dataclass
class StatsOptions:
    arrays: list[str] = field(default_factory=list)
    split: str = "train"
    scheme: str = "crossmodal"
    version: str | None = None
    wait_for_lock: bool = False


def _row_weights(seq: _SequenceReader, seq_ids: list[str], group: str, n_rows: int) -> np.ndarray:
    """How many times each global row of a ``group`` array counts: once per split sequence
    covering it (motion: its frames; audio: its aligned audio frames)."""
    weights = np.zeros(n_rows + 1, dtype=np.int64)
    for seq_id in seq_ids:
        row = seq.sequence(seq_id)
        if group == "motion":
            start, stop = int(row["frame_start"]), int(row["frame_stop"])
        else:
            n = seq.audio_frames(seq_id)
            start = seq.audio_start(seq_id)
            stop = start + n
        if not 0 <= start <= stop <= n_rows:
            raise InputError(
                f"sequence {seq_id}: rows {start}..{stop} lie outside {group} arrays of "
                f"{n_rows} rows"
            )
        weights[start] += 1
        weights[stop] -= 1
    return np.cumsum(weights)[:n_rows]


def _array_moments(reader: _VersionReader, name: str, weights: np.ndarray) -> Moments:
    array = reader.array(name)
    chunk = int(array.chunks[0]) or 1
    block = max(chunk, BLOCK_ROWS // chunk * chunk)
    used = np.flatnonzero(weights)
    total = Moments.empty(int(np.prod(array.shape[1:], dtype=np.int64)))
    if not used.size:
        return total
    for start in range(int(used[0]) // block * block, int(used[-1]) + 1, block):
        stop = min(start + block, array.shape[0])
        w = weights[start:stop]
        if w.any():
            total = total.add(Moments.of(np.asarray(array[start:stop]), w))
    return total


def _check_arrays(reader: _VersionReader, names: list[str]) -> list[str]:
    for name in names:
        group = name.split("/", 1)[0]
        if group not in ("motion", "audio") or "/" not in name:
            raise InputError(f"--arrays takes motion/<name> or audio/<name> paths, got {name!r}")
        if not reader.has_array(name):
            raise InputError(
                f"version {reader.version} has no array {name!r}; it has: "
                + ", ".join(n for n in reader.array_names() if n.startswith(group + "/"))
            )
        dtype = np.dtype(reader.array(name).dtype)
        if dtype.kind != "f":
            raise InputError(f"{name} holds {dtype}, not floats: no mean and std to take")
    return names


def stats(store: str | Path | StoreBackend, options: StatsOptions) -> CommandResult:
    """Compute the split's statistics of each array and write them as a new version derived
    from ``options.version`` (default: the latest, as it is once the lock is held)."""
    with derive_version(store, "stats", options.version, options.wait_for_lock) as step:
        return _stats_step(step, options)


def _stats_step(step: DerivedVersion, options: StatsOptions) -> CommandResult:
    import pyarrow as pa

    reader = step.reader
    names = options.arrays or [n for n in DEFAULT_ARRAYS if reader.has_array(n)]
    if not names:
        raise InputError(f"version {step.parent} has none of the default arrays; name --arrays")
    names = _check_arrays(reader, list(dict.fromkeys(names)))
    seq = _SequenceReader(reader)  # the step's open version, not a second open
    seq_ids = seq.split_members(options.split, options.scheme)
    if not seq_ids:
        raise InputError(f"split {options.split!r} of scheme {options.scheme!r} has no sequence")
    stages = reader.manifest.get("stages") or {}
    data = {stage: stages.get(stage) for stage in DATA_STAGES}
    if data["ingest"] is None:
        data["ingest"] = reader.manifest["fingerprint"]
    config = {
        "arrays": names,
        "split": {"scheme": options.scheme, "split": options.split},
        "std": f"population (ddof 0), float64; columns with std < {STD_FLOOR:g} divide by 1",
        "audio_rows": "each split sequence's aligned audio frames, counted per sequence",
        "data_stages": data,
    }
    fp = step.fingerprint(config, [str(v) for v in data.values()])
    done = step.already_done(fp)
    if done is not None:
        return done

    began = time.perf_counter()
    columns: dict[str, list[Any]] = {
        k: [] for k in ("array", "column", "mean", "std", "n_frames", "row_shape")
    }
    for name in names:
        array = reader.array(name)
        weights = _row_weights(seq, seq_ids, name.split("/", 1)[0], int(array.shape[0]))
        moments = _array_moments(reader, name, weights)
        width = moments.mean.size
        columns["array"] += [name] * width
        columns["column"] += list(range(width))
        columns["mean"] += moments.mean.tolist()
        columns["std"] += moments.std.tolist()
        columns["n_frames"] += [moments.count] * width
        columns["row_shape"] += [",".join(map(str, array.shape[1:]))] * width
    table = pa.table(
        {
            "array": pa.array(columns["array"], pa.string()),
            "column": pa.array(columns["column"], pa.int32()),
            "mean": pa.array(columns["mean"], pa.float64()),
            "std": pa.array(columns["std"], pa.float64()),
            "n_frames": pa.array(columns["n_frames"], pa.int64()),
            "row_shape": pa.array(columns["row_shape"], pa.string()),
        }
    )
    with step.writer(config, fp) as version:
        version.write_table("normalization", table)
        counts = {
            "arrays": len(names),
            "sequences": len(seq_ids),
            "seconds": round(time.perf_counter() - began, 3),
        }
        name = version.commit(counts)
    return CommandResult(version=name, created=True, counts=counts)
