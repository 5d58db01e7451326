"""Check a store against the contract in ``schemas/store.schema.json``.

Returns a list of problems (empty when the store is valid), each naming the version and the
table, array or file it concerns.
"""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np

from dancedata.errors import StoreError
from dancedata.store.contract import store_schema
from dancedata.store.fs import is_remote
from dancedata.store.integrity import verify_store
from dancedata.store.layout import StoreLayout
from dancedata.store.reader import VersionReader


def validate_store(
    store: str | Path, version: str | None = None, *, deep: bool = False
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
    # checksums.json is recorded by local commits only (remote stores: see store.remote)
    integrity = (
        {name: [] for name in names} if is_remote(store) else verify_store(store, names, deep=deep)
    )
    for name in names:
        problems += [f"{name}: {p}" for p in integrity[name]]
        problems += [f"{name}: {p}" for p in validate_version(VersionReader(store, name))]
    return problems


def validate_version(reader: VersionReader) -> list[str]:
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
    problems += _guarded("data.zarr", lambda: _check_arrays(reader, tables, schema))
    return problems


def _guarded(what: str, check: Callable[[], list[str]]) -> list[str]:
    """Run one check; a store damaged enough to make it fail (unreadable metadata, a chunk
    that does not decompress, a table missing a key column) is one problem, not a traceback."""
    try:
        return check()
    except Exception as exc:  # zarr, numcodecs and pyarrow raise many unrelated types
        return [f"{what}: cannot be read ({type(exc).__name__}: {exc})"]


def _check_manifest(reader: VersionReader, schema: dict[str, Any]) -> list[str]:
    try:
        manifest = reader.manifest
    except StoreError as exc:
        return [str(exc)]
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


def _check_ranges(reader: VersionReader, tables: dict[str, list[dict[str, Any]]]) -> list[str]:
    problems: list[str] = []
    sequences = tables.get("sequences", [])
    by_id = {s["seq_id"]: s for s in sequences}
    for seq in sequences:
        if seq["frame_stop"] - seq["frame_start"] != seq["n_frames"]:
            problems.append(f"sequences: {seq['seq_id']} frame range != n_frames")
    problems += _contiguous(sequences, "sequences")
    problems += _contiguous(tables.get("music", []), "music")
    for row in tables.get("measures", []):
        seq = by_id.get(row["seq_id"])
        if seq is None:
            problems.append(f"measures: unknown seq_id {row['seq_id']}")
        elif not (0 <= row["frame_start"] < row["frame_stop"] <= seq["n_frames"]):
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
    reader: VersionReader, tables: dict[str, list[dict[str, Any]]], schema: dict[str, Any]
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
        if array.dtype.kind == "f" and array.shape[0] and name.startswith("motion/"):
            sample = np.asarray(array[: min(array.shape[0], 4096)])
            if not np.all(np.isfinite(sample)) and name not in (
                "motion/keypoints3d",
                "motion/keypoints3d_optim",
                "motion/det_scores",
                "motion/positions",
            ):
                problems.append(f"{name}: holds NaN or Inf")
    return problems


def store_notes(store: str | Path) -> list[str]:
    """Things worth knowing that are not contract violations: unfinished temporary versions
    (never visible to readers; the next writer resumes or removes them) and the write lock."""
    from dancedata.store.lock import LOCK_FILE, describe_holder, judge_holder, read_holder

    layout = StoreLayout(store)
    if is_remote(store):
        return [
            f"unfinished temporary version {url.rsplit('/', 1)[-1]} (invisible to readers)"
            for url in layout.temp_dirs()
        ]
    notes = [
        f"unfinished temporary version {path.name} (invisible to readers; the next writer "
        "resumes or removes it)"
        for path in layout.temp_dirs()
    ]
    try:
        holder = read_holder(layout.root / LOCK_FILE)
    except StoreError as exc:
        return [*notes, str(exc)]
    if holder is not None:
        state = judge_holder(holder)
        notes.append(f"write lock {state.status}: {describe_holder(holder)}; {state.reason}")
    return notes
