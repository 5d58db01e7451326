"""Check a store against the contract in ``schemas/store.schema.json``.

Returns a list of problems (empty when the store is valid), each naming the version and the
table, array or file it concerns. Every row of every float array is checked for NaN and Inf,
chunk by chunk (memory: a few chunks, whatever the array size); an array whose attrs declare
NaN as its missing-value marker (``missing`` mentions NaN) may hold NaN but never ±Inf.
A damaged manifest (not an object, fields of the wrong type) is one problem, never a traceback.
"""

from __future__ import annotations

import re
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np

from dancedata.errors import StoreError
from dancedata.store.backend import StoreBackend
from dancedata.store.contract import store_schema
from dancedata.store.integrity import verify_store
from dancedata.store.layout import MANIFEST_FILE, ZARR_DIR, StoreLayout
from dancedata.store.reader import _VersionReader, metadata_problems
from dancedata.store.seq_ids import seq_id_problem
from dancedata.store.untrusted import MANIFEST_LIMIT, read_json


def validate_store(
    store: str | Path | StoreBackend, version: str | None = None, *, deep: bool = False
) -> list[str]:
    """Problems with ``store`` (every committed version, or only ``version``).

    Every version is also checked against the ``checksums.json`` recorded at its commit: files
    present with their recorded sizes, nothing unrecorded added. ``deep`` re-hashes every file
    (see :mod:`dancedata.store.integrity`) and names each corrupted chunk, array or table.
    """
    layout = StoreLayout(store)
    problems: list[str] = []
    try:
        pointer = layout.read_pointer()
    except StoreError as exc:
        return [str(exc)]
    for key in store_schema()["store_json"]["required"]:
        if key not in pointer:
            problems.append(f"store.json: missing {key!r}")
    committed = layout.committed_versions()
    if pointer.get("latest") is not None and pointer["latest"] not in committed:
        problems.append(f"store.json: latest {pointer['latest']!r} is not a committed version")
    if not committed:
        problems.append("store has no committed version")
    try:
        names = committed if version is None else [layout.resolve(version)]
    except StoreError as exc:
        return [*problems, str(exc)]
    # every backend: checksums.json read through the layout's backend (a version without one
    # passes the cheap check, and fails --deep: nothing could be verified)
    integrity = verify_store(layout.backend, names, deep=deep)
    if version is None:
        problems += _damaged_version_dirs(layout, committed)
    scanned: dict[Any, tuple[int, int]] = {}  # arrays shared by hard link are scanned once
    for name in names:
        problems += [f"{name}: {p}" for p in integrity[name]]
        try:
            reader = _VersionReader(layout, name)  # the store resolved once, above
        except StoreError as exc:
            problems.append(f"{name}: {exc}")
            continue
        metadata = metadata_problems(reader.files, limit=MAX_SHOWN)
        problems += [f"{name}: {p}" for p in metadata]
        # an unreadable chunk is already named by the integrity check: say it once
        found = validate_version(
            reader, report_unreadable=not integrity[name], scanned=scanned, arrays=not metadata
        )
        problems += [f"{name}: {p}" for p in found]
    return problems


_VERSION_NAME = re.compile(r"^v\d+$")

# validate prints the first MAX_SHOWN problems (each cut to MAX_PROBLEM_CHARS) and a count of
# the rest: a hostile store cannot make it print millions of lines.
MAX_SHOWN = 50
MAX_PROBLEM_CHARS = 500


def shown_problems(problems: list[str]) -> tuple[list[str], int]:
    """(the first MAX_SHOWN problems, each at most MAX_PROBLEM_CHARS long; how many more)."""
    shown = [
        p if len(p) <= MAX_PROBLEM_CHARS else p[: MAX_PROBLEM_CHARS - 1] + "…"
        for p in problems[:MAX_SHOWN]
    ]
    return shown, max(0, len(problems) - MAX_SHOWN)


def _damaged_version_dirs(layout: StoreLayout, committed: list[str]) -> list[str]:
    """One problem per ``versions/vN`` entry that is not a committed version (no manifest.json,
    or one that is not a usable manifest), naming the file. On object stores only the entries
    store.json commits are looked at: a copy past it is a dead writer's leftover, replaced by
    the next writer, not damage."""
    backend = layout.backend
    problems = []
    for name in layout.version_dirs():
        if name in committed:
            continue
        key = layout.version_key(name)
        entry = layout.version_dir(name)
        manifest = backend.where(f"{key}/{MANIFEST_FILE}")
        if not backend.is_dir(key):
            problems.append(f"{entry}: not a version directory")
        elif not backend.is_file(f"{key}/{MANIFEST_FILE}"):
            problems.append(f"{manifest}: missing (a damaged or half-restored version)")
        else:
            try:
                value = read_json(backend, f"{key}/{MANIFEST_FILE}", limit=MANIFEST_LIMIT)
            except (OSError, StoreError) as exc:
                problems.append(f"{manifest}: unreadable ({getattr(exc, 'problem', exc)})")
                continue
            found = manifest_type_problems(value) or ["not a usable manifest"]
            problems += [f"{manifest}: {p}" for p in found]
    return problems


def validate_version(
    reader: _VersionReader,
    *,
    report_unreadable: bool = True,
    scanned: dict[Any, tuple[int, int]] | None = None,
    arrays: bool = True,
) -> list[str]:
    """Problems of one version against the contract; ``report_unreadable`` False leaves out
    arrays that cannot be read for the finiteness scan (already reported elsewhere);
    ``scanned`` carries scan results between versions that share an array's files; ``arrays``
    False leaves data.zarr out (its metadata is already reported as untrustworthy)."""
    schema = store_schema()
    problems = _check_manifest(reader, schema)
    tables: dict[str, list[dict[str, Any]]] = {}
    for table, spec in schema["tables"].items():
        if not reader.has_table(table):
            if spec["required"]:
                problems.append(f"missing required table {table}")
            continue
        try:
            arrow = reader.table(table)
        except StoreError as exc:
            problems.append(str(exc))
            continue
        problems += _check_columns(table, arrow, spec)
        tables[table] = arrow.to_pylist()
    problems += _guarded("tables", lambda: _check_ranges(reader, tables))
    if not arrays:
        return problems
    problems += _guarded("data.zarr", lambda: _check_arrays(reader, tables, schema))
    problems += _guarded(
        "data.zarr",
        lambda: _check_finite(reader, report_unreadable, {} if scanned is None else scanned),
    )
    return problems


def _guarded(what: str, check: Callable[[], list[str]]) -> list[str]:
    """Run one check; a store damaged enough to make it fail (unreadable metadata, a chunk
    that does not decompress, a table missing a key column) is one problem, not a traceback."""
    try:
        return check()
    except Exception as exc:  # zarr, numcodecs and pyarrow raise many unrelated types
        return [f"{what}: cannot be read ({type(exc).__name__}: {exc})"]


# JSON types of the manifest fields other code relies on (None: null allowed).
_MANIFEST_TYPES: dict[str, tuple[type, ...]] = {
    "format_version": (int,),
    "version": (str,),
    "parent": (str, type(None)),
    "created_at": (str,),
    "dancedata_version": (str,),
    "command": (str,),
    "config": (dict,),
    "fingerprint": (str,),
    "stages": (dict,),
    "inputs": (list,),
    "skipped": (list,),
    "libraries": (dict,),
    "counts": (dict,),
}
_JSON_NAMES = {
    int: "an integer",
    str: "a string",
    dict: "an object",
    list: "a list",
    type(None): "null",
}


def _json_kind(value: Any) -> str:
    if isinstance(value, bool):
        return "a boolean"
    return _JSON_NAMES.get(type(value), f"a {type(value).__name__}")


def manifest_type_problems(manifest: Any) -> list[str]:
    """What is wrong with the shape of a parsed manifest.json: not an object, a field of the
    wrong JSON type, an ``inputs``/``skipped`` entry that is not an object, a ``stages`` value
    that is not a fingerprint string. Empty when the types are right."""
    if not isinstance(manifest, dict):
        return [f"is {_json_kind(manifest)}, not a JSON object"]
    problems = []
    for key, types in _MANIFEST_TYPES.items():
        value = manifest.get(key)
        if key in manifest and (not isinstance(value, types) or isinstance(value, bool)):
            wanted = " or ".join(_JSON_NAMES[t] for t in types)
            problems.append(f"{key!r} is {_json_kind(value)} ({value!r:.40}), expected {wanted}")
    for key in ("inputs", "skipped"):
        entries = manifest.get(key)
        if isinstance(entries, list):
            bad = [e for e in entries if not isinstance(e, dict)]
            if bad:
                problems.append(
                    f"{key!r} holds {len(bad)} entries that are not objects (first: {bad[0]!r:.40})"
                )
    stages = manifest.get("stages")
    if isinstance(stages, dict) and not all(isinstance(v, str) for v in stages.values()):
        problems.append("'stages' must map stage names to fingerprint strings")
    return problems


def _check_manifest(reader: _VersionReader, schema: dict[str, Any]) -> list[str]:
    try:
        manifest = reader.manifest
    except StoreError as exc:
        return [str(exc)]
    where = f"{reader.path}/{MANIFEST_FILE}"  # a Path or a URL
    shape = manifest_type_problems(manifest)
    if shape:
        return [f"{where}: {p}" for p in shape]
    spec = schema["manifest"]
    problems = [f"manifest.json: missing {k!r}" for k in spec["required"] if k not in manifest]
    if manifest.get("version") != reader.version:
        problems.append(f"manifest.json: version {manifest.get('version')!r} != directory name")
    for entry in manifest.get("inputs", []):
        missing = [k for k in spec["input_keys"] if k not in entry]
        if missing:
            problems.append(f"manifest.json: input entry missing {missing}")
    for entry in manifest.get("skipped", []):
        missing = [k for k in spec["skipped_keys"] if k not in entry]
        if missing:
            problems.append(f"manifest.json: skipped entry missing {missing}")
    return problems


def _check_columns(table: str, arrow: Any, spec: dict[str, Any]) -> list[str]:
    problems = []
    declared = {**spec["columns"], **spec.get("optional_columns", {})}
    for column, type_name in declared.items():
        if column not in arrow.column_names:
            if column in spec["columns"]:
                problems.append(f"{table}: missing column {column}")
            continue
        actual = str(arrow.schema.field(column).type)
        expected = {
            "string": "string",
            "float64": "double",
            "float32": "float",
            "int64": "int64",
            "int32": "int32",
            "int16": "int16",
            "bool": "bool",
        }[type_name]
        if actual not in (expected, "null"):
            problems.append(f"{table}.{column}: type {actual}, expected {type_name}")
    for column in spec.get("unique", []):
        if column in arrow.column_names:
            values = arrow.column(column).to_pylist()
            if len(values) != len(set(values)):
                problems.append(f"{table}.{column}: values are not unique")
    for column, allowed in spec.get("allowed_values", {}).items():
        if column in arrow.column_names:
            bad = sorted(set(arrow.column(column).to_pylist()) - set(allowed))
            if bad:
                problems.append(f"{table}.{column}: values {bad} not in {allowed}")
    return problems


def _contiguous(rows: list[dict[str, Any]], label: str) -> list[str]:
    problems = []
    position = 0
    for row in sorted(rows, key=lambda r: r["frame_start"]):
        if row["frame_start"] != position:
            problems.append(f"{label}: frame ranges not contiguous at {row['frame_start']}")
            break
        if row["frame_stop"] < row["frame_start"]:
            problems.append(f"{label}: negative frame range")
            break
        position = row["frame_stop"]
    return problems


def _check_ranges(reader: _VersionReader, tables: dict[str, list[dict[str, Any]]]) -> list[str]:
    problems: list[str] = []
    sequences = tables.get("sequences", [])
    by_id = {s["seq_id"]: s for s in sequences}
    bad_ids = [p for p in (seq_id_problem(s.get("seq_id")) for s in sequences) if p]
    problems += [f"sequences: {p}" for p in bad_ids[:5]]
    if len(bad_ids) > 5:
        problems.append(f"sequences: {len(bad_ids) - 5} more seq_id(s) that are not plain names")
    for seq in sequences:
        if seq["frame_stop"] - seq["frame_start"] != seq["n_frames"]:
            problems.append(f"sequences: {seq['seq_id']} frame range != n_frames")
    problems += _contiguous(sequences, "sequences")
    problems += _contiguous(tables.get("music", []), "music")
    for row in tables.get("measures", []):
        owner = by_id.get(row["seq_id"])
        if owner is None:
            problems.append(f"measures: unknown seq_id {row['seq_id']}")
        elif not (0 <= row["frame_start"] < row["frame_stop"] <= owner["n_frames"]):
            problems.append(f"measures: {row['seq_id']} measure {row['measure']} out of range")
    for row in tables.get("splits", []):
        if row["seq_id"] not in by_id:
            problems.append(f"splits: unknown seq_id {row['seq_id']}")
    music_ids = {m["music_id"] for m in tables.get("music", [])}
    for seq in sequences:
        if (
            seq.get("music_id")
            and seq["music_id"] not in music_ids
            and not seq.get("music_missing")
            and tables.get("music") is not None
        ):
            problems.append(
                f"sequences: {seq['seq_id']} names music {seq['music_id']} "
                "that the music table lacks"
            )
    return problems


def _check_arrays(
    reader: _VersionReader, tables: dict[str, list[dict[str, Any]]], schema: dict[str, Any]
) -> list[str]:
    problems: list[str] = []
    lengths = {
        "sequences": max((s["frame_stop"] for s in tables.get("sequences", [])), default=0),
        "music": max((m["frame_stop"] for m in tables.get("music", [])), default=0),
    }
    motion_attrs = reader.group_attrs("motion")
    skeleton = motion_attrs.get("skeleton") or {}
    n_joints = len(skeleton.get("joints", [])) or None
    for group, keys in schema["group_attrs"].items():
        has_arrays = any(n.startswith(group + "/") for n in reader.array_names())
        attrs = reader.group_attrs(group)
        if has_arrays:
            problems += [f"{group} attrs: missing {k!r}" for k in keys if k not in attrs]
    for name in reader.array_names():
        spec = schema["arrays"].get(name)
        if spec is None:
            continue
        array = reader.array(name)
        if str(array.dtype) != spec["dtype"]:
            problems.append(f"{name}: dtype {array.dtype}, expected {spec['dtype']}")
        expected_tail = tuple(n_joints if d == "J" else d for d in spec["row_shape"])
        tail = tuple(array.shape[1:])
        if len(tail) != len(expected_tail) or any(
            e is not None and e != t for e, t in zip(expected_tail, tail, strict=False)
        ):
            problems.append(f"{name}: row shape {tail}, expected {expected_tail}")
        expected_rows = lengths[spec["index"]]
        if array.shape[0] != expected_rows:
            problems.append(
                f"{name}: {array.shape[0]} rows but the {spec['index']} table spans {expected_rows}"
            )
        for attr in spec.get("attrs", []):
            if attr not in array.attrs:
                problems.append(f"{name}: missing attr {attr!r}")
    return problems


# The finiteness scan reads up to this many chunks per call (zarr decodes them on parallel
# threads), and no more than _SCAN_BYTES of decoded values: memory stays bounded by that.
_SCAN_CHUNKS = 4
_SCAN_BYTES = 32 << 20


def nan_allowed(attrs: Any) -> bool:
    """True when an array's attrs declare NaN as its missing-value marker."""
    missing = attrs.get("missing") if hasattr(attrs, "get") else None
    return isinstance(missing, str) and "nan" in missing.lower()


def scan_chunks(array: Any) -> int:
    """Chunks per read for :func:`nonfinite_rows`: up to _SCAN_CHUNKS, within _SCAN_BYTES."""
    rows = int(array.chunks[0]) if array.ndim else 1
    row_bytes = int(np.prod(array.shape[1:], dtype=np.int64)) * np.dtype(array.dtype).itemsize
    return int(max(1, min(_SCAN_CHUNKS, _SCAN_BYTES // max(1, rows * row_bytes))))


def nonfinite_rows(array: Any, *, allow_nan: bool, chunks: int | None = None) -> tuple[int, int]:
    """(rows holding a value that is not allowed, first such row) over every row of a float
    array, read ``chunks`` chunks along axis 0 at a time (default :func:`scan_chunks`; bounded
    memory). Not allowed: NaN and ±Inf, or only ±Inf when ``allow_nan``. (0, -1) when every
    row is clean."""
    n_rows = int(array.shape[0]) if array.ndim else 1
    chunks = scan_chunks(array) if chunks is None else chunks
    step = max(1, int(array.chunks[0]) if array.ndim else 1) * chunks
    bad_rows, first = 0, -1
    for start in range(0, n_rows, step):
        block = np.asarray(array[start : start + step] if array.ndim else array[...])
        if block.size == 0:
            continue
        # min and max propagate NaN and show ±Inf without allocating a boolean array; fmin and
        # fmax skip NaN. Only a block that fails them is examined row by row.
        if allow_nan:
            lo, hi = np.fmin.reduce(block, axis=None), np.fmax.reduce(block, axis=None)
        else:
            lo, hi = block.min(), block.max()
        if np.isfinite(lo) and np.isfinite(hi) or (allow_nan and np.isnan(lo) and np.isnan(hi)):
            continue
        flat = block.reshape(block.shape[0], -1) if block.ndim > 1 else block.reshape(-1, 1)
        bad = np.isinf(flat) if allow_nan else ~np.isfinite(flat)
        rows = np.flatnonzero(bad.any(axis=1))
        if rows.size:
            if first < 0:
                first = start + int(rows[0])
            bad_rows += int(rows.size)
    return bad_rows, first


def _array_files_key(reader: _VersionReader, name: str, allow_nan: bool) -> Any:
    """What identifies an array's values in storage: shape, dtype and the identity of each
    chunk file (an inode locally: versions that carry the array over by hard link share them;
    its zarr.json is a copy, so it is left out); None where the backend cannot tell (object
    stores: every version holds its own objects)."""
    array = reader.array(name)
    folder = f"{ZARR_DIR}/{name}"
    chunks = []
    for rel in reader.files.find(folder):
        if rel == "zarr.json":
            continue
        identity = reader.files.identity(f"{folder}/{rel}")
        if identity is None:
            return None
        chunks.append((rel, identity))
    return (tuple(array.shape), str(array.dtype), allow_nan, tuple(sorted(chunks)))


def _check_finite(
    reader: _VersionReader, report_unreadable: bool, scanned: dict[Any, tuple[int, int]]
) -> list[str]:
    """Every row of every float array is finite (NaN allowed where the attrs say so)."""
    problems: list[str] = []
    for name in reader.array_names():
        array = reader.array(name)
        if array.dtype.kind != "f":
            continue
        allow_nan = nan_allowed(array.attrs)
        key = _array_files_key(reader, name, allow_nan)
        try:
            if key is not None and key in scanned:
                bad, first = scanned[key]
            else:
                bad, first = nonfinite_rows(array, allow_nan=allow_nan)
        except StoreError as exc:
            if report_unreadable:
                problems.append(f"{name}: not checked for NaN/Inf: {exc}")
            continue
        if key is not None:
            scanned[key] = (bad, first)
        if bad:
            what = "Inf" if allow_nan else "NaN or Inf"
            problems.append(f"{name}: {bad} rows hold {what} (first: row {first})")
    return problems


def store_notes(store: str | Path | StoreBackend) -> list[str]:
    """Things worth knowing that are not contract violations: unfinished temporary versions
    (never visible to readers; the next writer resumes or removes them) and the write lock,
    on every backend."""
    from dancedata.store.lock import describe_holder, judge_holder, read_store_holder

    layout = StoreLayout(store)
    notes = [
        f"unfinished temporary version {name} (invisible to readers; the next writer "
        "resumes or removes it)"
        for name in layout.temp_names()
    ]
    try:
        holder = read_store_holder(layout.backend)
    except StoreError as exc:
        return [*notes, str(exc)]
    if holder is not None:
        state = judge_holder(holder)
        notes.append(f"write lock {state.status}: {describe_holder(holder)}; {state.reason}")
    return notes
