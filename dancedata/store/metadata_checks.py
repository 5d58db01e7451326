"""Schema checks of what a store declares, run before anything is computed from it.

A store is untrusted input (:mod:`dancedata.store.untrusted`): its zarr metadata, group
attributes and tables are checked when a reader opens them, so that no command divides by a
frame rate of 0, allocates an array a shape of 1e12 elements asks for, or walks a skeleton whose
parents form a cycle. Each check returns a one-line problem or None.

Bounds (documented in docs/STORE.md, "Untrusted stores"):

* arrays: zarr v3, rank at most :data:`MAX_RANK`, every dimension a non-negative integer below
  2**40, at most :data:`MAX_ELEMENTS` elements and :data:`MAX_CHUNKS` chunks, a chunk of at most
  :data:`MAX_CHUNK_BYTES` decoded; data types and codecs from the lists below only;
* frame rates (``fps``) finite in (0, :data:`MAX_FPS`]; sample rates in [1, 10**6] Hz; tempi
  (``bpm``) NaN, null or 0 (unknown) or finite in (0, :data:`MAX_BPM`]; frame numbers and
  counts integers in [0, :data:`MAX_FRAME`];
* a skeleton: joint names strings, one parent per joint, exactly one root (-1), every other
  parent a joint index, no cycle.
"""

from __future__ import annotations

import math
from typing import Any

MAX_RANK = 8
MAX_DIM = 2**40
MAX_ELEMENTS = 2**40
MAX_CHUNKS = 1_000_000
MAX_CHUNK_BYTES = 256 * 1024 * 1024
MAX_FPS = 10_000.0
MAX_BPM = 1_000.0
MAX_FRAME = 2**40
MAX_SR = 1_000_000

ITEM_BYTES = {
    "bool": 1,
    "int8": 1,
    "uint8": 1,
    "int16": 2,
    "uint16": 2,
    "int32": 4,
    "uint32": 4,
    "int64": 8,
    "uint64": 8,
    "float16": 2,
    "float32": 4,
    "float64": 8,
}
# Codecs whose decoded size is known before decoding: bytes (the array's own), transpose, zstd
# (the frame header declares its content size), blosc (its header does), crc32c (4 bytes).
CODECS = frozenset({"bytes", "transpose", "zstd", "blosc", "crc32c"})


def _is_int(value: Any) -> bool:
    return isinstance(value, int) and not isinstance(value, bool)


def _is_number(value: Any) -> bool:
    return isinstance(value, int | float) and not isinstance(value, bool)


def _ints(value: Any, what: str, *, positive: bool) -> tuple[tuple[int, ...] | None, str | None]:
    if not isinstance(value, list) or len(value) > MAX_RANK:
        return None, f"{what} must be a list of at most {MAX_RANK} integers, not {value!r:.60}"
    low = 1 if positive else 0
    for n in value:
        if not _is_int(n) or not low <= n < MAX_DIM:
            return None, (
                f"{what} {value!r:.80} holds {n!r:.30}: every entry must be an integer in "
                f"[{low}, 2**40)"
            )
    return tuple(value), None


def array_meta_problem(meta: Any) -> str | None:
    """What makes a parsed zarr.json of an array unusable, or None (also None for groups)."""
    if not isinstance(meta, dict):
        return f"zarr metadata is {type(meta).__name__}, not an object"
    if meta.get("node_type") != "array":
        if meta.get("node_type") != "group":
            return f"node_type {meta.get('node_type')!r:.40} is neither 'array' nor 'group'"
        return None
    if meta.get("zarr_format") != 3:
        return f"zarr_format {meta.get('zarr_format')!r:.20}, this reader reads 3"
    shape, problem = _ints(meta.get("shape"), "shape", positive=False)
    if problem:
        return problem
    dtype = meta.get("data_type")
    if not isinstance(dtype, str) or dtype not in ITEM_BYTES:
        return f"unknown data type {dtype!r:.40} (known: {', '.join(ITEM_BYTES)})"
    grid = meta.get("chunk_grid")
    config = grid.get("configuration") if isinstance(grid, dict) else None
    if not isinstance(grid, dict) or grid.get("name") != "regular" or not isinstance(config, dict):
        return f"chunk_grid {grid!r:.60} is not a regular grid"
    chunk_shape, problem = _ints(config.get("chunk_shape"), "chunk shape", positive=True)
    if problem:
        return problem
    assert shape is not None and chunk_shape is not None
    if len(shape) != len(chunk_shape):
        return f"chunk shape {list(chunk_shape)} and shape {list(shape)} differ in rank"
    elements = math.prod(shape)
    if elements > MAX_ELEMENTS:
        return f"shape {list(shape)} declares {elements:.3g} elements, over the limit of 2**40"
    chunks = math.prod(-(-n // c) for n, c in zip(shape, chunk_shape, strict=True))
    if chunks > MAX_CHUNKS:
        return (
            f"shape {list(shape)} and chunk shape {list(chunk_shape)} declare {chunks:.3g} "
            f"chunks, over the limit of {MAX_CHUNKS:,}"
        )
    chunk_bytes = math.prod(chunk_shape) * ITEM_BYTES[dtype]
    if chunk_bytes > MAX_CHUNK_BYTES:
        return (
            f"chunk shape {list(chunk_shape)} of {dtype} is {chunk_bytes:,} bytes decoded, over "
            f"the limit of {MAX_CHUNK_BYTES:,}"
        )
    codecs = meta.get("codecs")
    if not isinstance(codecs, list) or not codecs:
        return "codecs must be a non-empty list"
    for codec in codecs:
        name = codec.get("name") if isinstance(codec, dict) else codec
        if not isinstance(name, str) or name not in CODECS:
            return f"unknown codec {name!r:.40} (known: {', '.join(sorted(CODECS))})"
    for key in ("storage_transformers",):
        if meta.get(key):
            return f"{key} {meta[key]!r:.40} are not supported"
    return None


def decoded_chunk_bytes(meta: dict[str, Any]) -> int:
    """Bytes of one decoded chunk of a checked array (see :func:`array_meta_problem`)."""
    shape = meta["chunk_grid"]["configuration"]["chunk_shape"]
    return math.prod(shape) * ITEM_BYTES[meta["data_type"]]


def fps_problem(value: Any, what: str = "fps") -> str | None:
    """A frame rate must be a finite number in (0, MAX_FPS]."""
    if not _is_number(value) or not math.isfinite(value) or not 0 < value <= MAX_FPS:
        return f"{what} {value!r:.30} is not a frame rate (a finite number in (0, {MAX_FPS:g}])"
    return None


def skeleton_problem(skeleton: Any) -> str | None:
    """A skeleton must name its joints, give one parent per joint, have exactly one root
    (parent -1) and no cycle (every joint reaches the root)."""
    if not isinstance(skeleton, dict):
        return f"skeleton {skeleton!r:.40} is not an object"
    joints, parents = skeleton.get("joints"), skeleton.get("parents")
    if not isinstance(joints, list) or not all(isinstance(j, str) for j in joints):
        return "skeleton joints must be a list of names"
    if not isinstance(parents, list) or len(parents) != len(joints):
        return f"skeleton parents must be a list of {len(joints)} joint indices (one per joint)"
    n = len(parents)
    if not all(_is_int(p) and -1 <= p < n for p in parents):
        bad = next(p for p in parents if not (_is_int(p) and -1 <= p < n))
        return f"skeleton parent {bad!r:.30} is not -1 or a joint index in [0, {n})"
    roots = [i for i, p in enumerate(parents) if p == -1]
    if n and len(roots) != 1:
        return f"skeleton has {len(roots)} roots (parent -1), expected exactly one"
    depth = [0 if p == -1 else -1 for p in parents]  # -1: not yet known
    for start in range(n):
        path: list[int] = []
        on_path: set[int] = set()
        joint = start
        while depth[joint] < 0:
            if joint in on_path:
                name = joints[joint]
                return f"skeleton parents form a cycle through joint {joint} ({name!r:.40})"
            path.append(joint)
            on_path.add(joint)
            joint = parents[joint]
        for k, j in enumerate(reversed(path), start=1):
            depth[j] = depth[joint] + k
    return None


def group_attrs_problem(group: str, attrs: Any) -> str | None:
    """The attributes dancedata computes from: ``fps``, ``sr``, ``hop_length``, ``skeleton``."""
    if not isinstance(attrs, dict):
        return f"group {group or '/'} attributes are not an object"
    if "fps" in attrs and (problem := fps_problem(attrs["fps"], f"group {group} fps")):
        return problem
    for key, high in (("sr", MAX_SR), ("hop_length", MAX_SR), ("n_fft", MAX_SR)):
        if key in attrs and not (_is_int(attrs[key]) and 1 <= attrs[key] <= high):
            return f"group {group} {key} {attrs[key]!r:.30} is not an integer in [1, {high}]"
    if "skeleton" in attrs and (problem := skeleton_problem(attrs["skeleton"])):
        return f"group {group}: {problem}"
    return None


# Table columns with value bounds: (column, kind). Kinds: "fps", "bpm", "frame" (a non-negative
# frame number or count), "offset" (a signed frame offset), "sr".
TABLE_BOUNDS: dict[str, tuple[tuple[str, str], ...]] = {
    "sequences": (
        ("fps", "fps"),
        ("bpm", "bpm"),
        ("n_frames", "frame"),
        ("frame_start", "frame"),
        ("frame_stop", "frame"),
        ("audio_offset", "offset"),
        ("audio_frames", "frame"),
    ),
    "music": (
        ("bpm", "bpm"),
        ("sr", "sr"),
        ("n_samples", "frame"),
        ("frame_start", "frame"),
        ("frame_stop", "frame"),
    ),
    "measures": (
        ("measure", "frame"),
        ("frame_start", "frame"),
        ("frame_stop", "frame"),
        ("bpm", "bpm"),
    ),
    "beats": (
        ("beat", "frame"),
        ("frame", "frame"),
        ("measure", "frame"),
        ("beat_in_measure", "frame"),
        ("bpm", "bpm"),
    ),
    "phrases": (
        ("phrase", "frame"),
        ("measure_start", "frame"),
        ("measure_stop", "frame"),
        ("frame_start", "frame"),
        ("frame_stop", "frame"),
    ),
    "normalization": (("column", "frame"), ("n_frames", "frame")),
    "keyframes": (
        ("frame", "frame"),
        ("frame_in_sequence", "frame"),
        ("measure", "frame"),
        ("k", "frame"),
        ("n_keyframes", "frame"),
    ),
}


def _column_problem(table: Any, column: str, kind: str) -> str | None:
    import numpy as np
    import pyarrow as pa

    values = table.column(column)
    if pa.types.is_null(values.type) or values.null_count == len(values):
        return None
    if not (pa.types.is_integer(values.type) or pa.types.is_floating(values.type)):
        return None  # another type: column_type_problem names it
    # plain Python values, no pyarrow compute kernel: those start Arrow's thread pool, and a
    # process exiting right after (a refusal) then aborts now and then (SIGABRT)
    data = np.array([v for v in values.to_pylist() if v is not None], dtype=np.float64)
    if kind == "bpm":
        data = data[~np.isnan(data)]
        bad = ~np.isfinite(data) | (data < 0) | (data > MAX_BPM)
        rule = f"a tempo is unknown (NaN, 0) or a finite number in (0, {MAX_BPM:g}]"
    elif kind == "fps":
        bad = ~np.isfinite(data) | (data <= 0) | (data > MAX_FPS)
        rule = f"a frame rate is a finite number in (0, {MAX_FPS:g}]"
    elif kind == "sr":
        bad = ~np.isfinite(data) | (data < 1) | (data > MAX_SR) | (data != np.round(data))
        rule = f"a sample rate is an integer in [1, {MAX_SR}]"
    else:
        low = -MAX_FRAME if kind == "offset" else 0
        bad = ~np.isfinite(data) | (data < low) | (data > MAX_FRAME)
        rule = f"a frame number is in [{low}, 2**40]"
    if not bad.any():
        return None
    index = int(np.flatnonzero(bad)[0])
    value = float(data[index])
    shown = f"{int(value)}" if value.is_integer() and abs(value) < 1e18 else f"{value:g}"
    return f"{column} {shown} ({int(bad.sum())} rows out of range): {rule}"


def _kind_of_arrow(arrow_type: Any) -> str:
    import pyarrow as pa

    if pa.types.is_null(arrow_type):
        return "null"
    if pa.types.is_integer(arrow_type) or pa.types.is_floating(arrow_type):
        return "number"
    if pa.types.is_string(arrow_type) or pa.types.is_large_string(arrow_type):
        return "string"
    if pa.types.is_boolean(arrow_type):
        return "bool"
    return str(arrow_type)


# The contract's column types (schemas/store.schema.json) by kind: a reader may take an int64
# where the contract says float64, but never a string where it computes with a number.
_CONTRACT_KINDS = {
    "float64": "number",
    "float32": "number",
    "int64": "number",
    "int32": "number",
    "int16": "number",
    "string": "string",
    "bool": "bool",
}


def column_type_problem(name: str, table: Any) -> str | None:
    """The first column of a contract table whose type is of another kind than the contract's
    (a string of frame rates, integer seq_ids), or None. Unknown tables and columns pass."""
    from dancedata.store.contract import store_schema

    spec = store_schema()["tables"].get(name)
    if not isinstance(spec, dict):
        return None
    declared = {**spec.get("columns", {}), **spec.get("optional_columns", {})}
    for column, type_name in declared.items():
        if column not in table.column_names or type_name not in _CONTRACT_KINDS:
            continue
        actual = table.schema.field(column).type
        kind = _kind_of_arrow(actual)
        if kind not in ("null", _CONTRACT_KINDS[type_name]):
            return f"column {column} is of type {actual}, expected {type_name}"
    return None


def table_problem(name: str, table: Any) -> str | None:
    """The first column of a known table of the wrong kind of type, or the first value of a
    bounded column that no computation may start from."""
    problem = column_type_problem(name, table)
    if problem is not None:
        return problem
    for column, kind in TABLE_BOUNDS.get(name, ()):
        if column in table.column_names:
            problem = _column_problem(table, column, kind)
            if problem is not None:
                return problem
    return None


# -- manifest counts ---------------------------------------------------------------------------
_COUNT_INTS = (
    "sequences",
    "measures",
    "units",
    "resumed_units",
    "frames",
    "music",
    "skipped",
    "rows",
    "music_tracks",
    "motion_frames",
    "audio_frames",
)


def counts_problem(counts: Any) -> str | None:
    """The manifest's ``counts``: an object; the counts readers compute from are non-negative
    integers, and ``splits`` (the split files ingest read) maps schemes to splits to counts."""
    if not isinstance(counts, dict):
        return None  # the field type check names it
    for key in _COUNT_INTS:
        if key in counts and not (_is_int(counts[key]) and counts[key] >= 0):
            return f"counts {key!r} is {counts[key]!r:.40}, expected a non-negative integer"
    splits = counts.get("splits")
    if splits is None:
        return None
    if not isinstance(splits, dict):
        return f"counts 'splits' is {splits!r:.40}, expected an object"
    schemes = splits.get("schemes", {})
    if not isinstance(schemes, dict):
        return f"counts 'splits.schemes' is {schemes!r:.40}, expected an object"
    for scheme, per_split in schemes.items():
        if not isinstance(per_split, dict):
            return f"counts 'splits.schemes.{scheme:.40}' is not an object"
        for split, numbers in per_split.items():
            if not isinstance(numbers, dict) or not all(
                _is_int(v) and v >= 0 for v in numbers.values()
            ):
                return (
                    f"counts 'splits.schemes.{scheme:.40}.{split:.40}' must map names to "
                    f"non-negative integers, not {numbers!r:.60}"
                )
    for key, value in splits.items():
        if key != "schemes" and not (_is_int(value) and value >= 0):
            return f"counts 'splits.{key:.40}' is {value!r:.40}, expected a non-negative integer"
    return None
