"""The store contract from ``schemas/store.schema.json``, and Arrow tables built to match it."""

from __future__ import annotations

import json
from functools import cache
from importlib import resources
from typing import TYPE_CHECKING, Any

from dancedata.errors import StoreError

if TYPE_CHECKING:
    import pyarrow as pa


@cache
def store_schema() -> dict[str, Any]:
    """The parsed contract (installed as package data ``dancedata.schemas``)."""
    text = resources.files("dancedata.schemas").joinpath("store.schema.json").read_text("utf-8")
    return json.loads(text)


def _arrow_type(name: str) -> pa.DataType:
    import pyarrow as pa

    return {
        "string": pa.string(),
        "float64": pa.float64(),
        "float32": pa.float32(),
        "int64": pa.int64(),
        "int32": pa.int32(),
        "int16": pa.int16(),
        "bool": pa.bool_(),
    }[name]


def column_types(table: str) -> dict[str, str]:
    """Declared type of every required and optional column of ``table``."""
    spec = store_schema()["tables"][table]
    return {**spec["columns"], **spec.get("optional_columns", {})}


def build_table(table: str, rows: list[dict[str, Any]]) -> pa.Table:
    """An Arrow table from row dicts: contract columns first, cast to their declared types,
    then any extra columns with inferred types. Missing required columns are an error."""
    import pyarrow as pa

    spec = store_schema()["tables"][table]
    declared = column_types(table)
    names: list[str] = list(spec["columns"])
    for row in rows:
        for key in row:
            if key not in names:
                names.append(key)
    missing = [c for c in spec["columns"] if rows and c not in rows[0]]
    if missing:
        raise StoreError(f"table {table!r} is missing contract columns {missing}")
    arrays = []
    fields = []
    for name in names:
        values = [row.get(name) for row in rows]
        arrow_type = _arrow_type(declared[name]) if name in declared else None
        array = pa.array(values, type=arrow_type)
        arrays.append(array)
        fields.append(pa.field(name, array.type))
    return pa.Table.from_arrays(arrays, schema=pa.schema(fields))
