"""A Croissant record (MLCommons' JSON-LD dataset metadata, format 1.0) of one store version.

What it holds, all read from the committed version:

* ``distribution``: a ``cr:FileObject`` per parquet table (sha256 of its bytes, checked against
  the version's ``checksums.json``), one for ``checksums.json`` itself (its sha256 covers the
  sha256 of every Zarr file it lists) and a ``cr:FileSet`` for the Zarr arrays
  (``data.zarr/**``);
* ``recordSet``: ``sequences``, ``measures`` and ``splits`` (one field per parquet column, read
  from the table's file) and ``arrays``, an inline record per Zarr array: name, shape, dtype,
  chunks and units (rows of motion arrays are global motion frames, rows of audio arrays global
  audio feature frames; each sequence's slice is in the sequences and music tables);
* ``license`` and ``citeAs`` as the user gives them, ``version`` (the store version's number
  as ``N.0.0``), ``datePublished`` (when the version was committed), and in ``description`` and
  ``identifier`` the store version name, its fingerprint and the dancedata version that wrote
  it, with the split counts.

``contentUrl`` values are relative to the version folder (``versions/vN/``), or to
``base_url`` when given: the record is meant to sit next to the files it describes when the
version is published, and never to be written into the store itself.
"""

from __future__ import annotations

import hashlib
import json
from pathlib import Path
from typing import Any

from dancedata.errors import StoreError
from dancedata.store.backend import StoreBackend
from dancedata.store.layout import TABLE_FILES
from dancedata.store.reader import _VersionReader

CONFORMS_TO = "http://mlcommons.org/croissant/1.0"
CONTEXT: dict[str, Any] = {
    "@language": "en",
    "@vocab": "https://schema.org/",
    "sc": "https://schema.org/",
    "cr": "http://mlcommons.org/croissant/",
    "rai": "http://mlcommons.org/croissant/RAI/",
    "dct": "http://purl.org/dc/terms/",
    "citeAs": "cr:citeAs",
    "column": "cr:column",
    "conformsTo": "dct:conformsTo",
    "data": {"@id": "cr:data", "@type": "@json"},
    "dataType": {"@id": "cr:dataType", "@type": "@vocab"},
    "examples": {"@id": "cr:examples", "@type": "@json"},
    "extract": "cr:extract",
    "field": "cr:field",
    "fileProperty": "cr:fileProperty",
    "fileObject": "cr:fileObject",
    "fileSet": "cr:fileSet",
    "format": "cr:format",
    "includes": "cr:includes",
    "isLiveDataset": "cr:isLiveDataset",
    "jsonPath": "cr:jsonPath",
    "key": "cr:key",
    "md5": "cr:md5",
    "parentField": "cr:parentField",
    "path": "cr:path",
    "recordSet": "cr:recordSet",
    "references": "cr:references",
    "regex": "cr:regex",
    "repeated": "cr:repeated",
    "replace": "cr:replace",
    "samplingRate": "cr:samplingRate",
    "equivalentProperty": "cr:equivalentProperty",
    "separator": "cr:separator",
    "source": "cr:source",
    "subField": "cr:subField",
    "transform": "cr:transform",
}
RECORD_TABLES = ("sequences", "measures", "splits")
PARQUET = "application/x-parquet"


def _data_type(arrow_type: Any) -> str:
    """The schema.org data type of a pyarrow column type."""
    import pyarrow as pa

    if pa.types.is_boolean(arrow_type):
        return "sc:Boolean"
    if pa.types.is_integer(arrow_type):
        return "sc:Integer"
    if pa.types.is_floating(arrow_type):
        return "sc:Float"
    if pa.types.is_timestamp(arrow_type) or pa.types.is_date(arrow_type):
        return "sc:Date"
    return "sc:Text"


def _table_file(reader: _VersionReader, name: str, recorded: dict[str, Any]) -> dict[str, Any]:
    """The FileObject of table ``name``: its bytes hashed and checked against checksums.json."""
    key = TABLE_FILES[name]
    data = reader.files.read_bytes(key)
    sha = hashlib.sha256(data).hexdigest()
    expected = (recorded.get(key) or {}).get("sha256")
    if expected is not None and expected != sha:
        raise StoreError(
            f"{key} does not match its sha256 in checksums.json (run dancedata validate)",
            reader.files.where(key),
        )
    return {
        "@type": "cr:FileObject",
        "@id": key,
        "name": key,
        "contentUrl": key,
        "encodingFormat": PARQUET,
        "contentSize": f"{len(data)} B",
        "sha256": sha,
    }


def _table_record_set(reader: _VersionReader, name: str) -> dict[str, Any]:
    key = TABLE_FILES[name]
    fields = [
        {
            "@type": "cr:Field",
            "@id": f"{name}/{column.name}",
            "name": column.name,
            "dataType": _data_type(column.type),
            "source": {"fileObject": {"@id": key}, "extract": {"column": column.name}},
        }
        for column in reader.table(name).schema
    ]
    return {"@type": "cr:RecordSet", "@id": name, "name": name, "field": fields}


ARRAY_FIELDS = (
    ("name", "array path in data.zarr, e.g. motion/rotmat"),
    ("shape", "shape, comma-separated; axis 0 is global frames"),
    ("dtype", "numpy dtype"),
    ("chunks", "chunk shape, comma-separated"),
    ("units", "units attribute ('1' dimensionless, 'm' metres, ... ; '' when unrecorded)"),
)


def _array_record_set(reader: _VersionReader) -> dict[str, Any]:
    records = []
    for name in reader.array_names():
        array = reader.array(name)
        records.append(
            {
                f"arrays/{field}": value
                for field, value in zip(
                    (f for f, _ in ARRAY_FIELDS),
                    (
                        name,
                        ",".join(str(n) for n in array.shape),
                        str(array.dtype),
                        ",".join(str(n) for n in array.chunks),
                        str(array.attrs.get("units", "")),
                    ),
                    strict=True,
                )
            }
        )
    fields = [
        {
            "@type": "cr:Field",
            "@id": f"arrays/{field}",
            "name": field,
            "description": text,
            "dataType": "sc:Text",
        }
        for field, text in ARRAY_FIELDS
    ]
    return {
        "@type": "cr:RecordSet",
        "@id": "arrays",
        "name": "arrays",
        "description": "The Zarr v3 arrays of data.zarr (the FileSet data-zarr), one per record.",
        "key": {"@id": "arrays/name"},
        "field": fields,
        "data": records,
    }


def _split_counts(reader: _VersionReader) -> str:
    counts: dict[tuple[str, str], int] = {}
    for row in reader.table("splits").to_pylist():
        key = (str(row["scheme"]), str(row["split"]))
        counts[key] = counts.get(key, 0) + 1
    return "; ".join(f"{scheme}/{split}: {n}" for (scheme, split), n in sorted(counts.items()))


def croissant_record(
    store: str | Path | StoreBackend,
    version: str | None = None,
    *,
    license: str | None = None,
    citation: str | None = None,
    name: str | None = None,
    base_url: str | None = None,
) -> dict[str, Any]:
    """The Croissant 1.0 JSON-LD record of ``version`` (latest when None) of ``store``."""
    reader = _VersionReader(store, version)
    manifest = reader.manifest
    try:
        recorded = json.loads(reader.files.read_bytes("checksums.json"))
    except FileNotFoundError:
        raise StoreError(
            f"version {reader.version} has no checksums.json", reader.files.where("")
        ) from None
    files = recorded.get("files") or {}
    tables = [t for t in RECORD_TABLES if reader.has_table(t)]
    others = [t for t in TABLE_FILES if t not in tables and reader.has_table(t)]
    distribution = [_table_file(reader, t, files) for t in tables + others]
    checksums = reader.files.read_bytes("checksums.json")
    distribution.append(
        {
            "@type": "cr:FileObject",
            "@id": "checksums.json",
            "name": "checksums.json",
            "description": "sha256 of every file of the version, Zarr chunks included",
            "contentUrl": "checksums.json",
            "encodingFormat": "application/json",
            "sha256": hashlib.sha256(checksums).hexdigest(),
        }
    )
    distribution.append(
        {
            "@type": "cr:FileSet",
            "@id": "data-zarr",
            "name": "data.zarr",
            "description": "Zarr v3 arrays; per-file sha256 in checksums.json",
            "encodingFormat": "application/x-zarr",
            "includes": "data.zarr/**",
        }
    )
    if base_url:
        base = base_url.rstrip("/") + "/"
        for entry in distribution:
            if "contentUrl" in entry:
                entry["contentUrl"] = base + entry["contentUrl"]
    record_sets = [_table_record_set(reader, t) for t in tables] + [_array_record_set(reader)]
    store_name = name or Path(str(store).rstrip("/")).name or "dancedata-store"
    number = reader.version.lstrip("v")
    description = (
        f"dancedata store {store_name}, version {reader.version} (fingerprint "
        f"{manifest.get('fingerprint')}, written by dancedata {manifest.get('dancedata_version')})."
        f" Splits: {_split_counts(reader) if reader.has_table('splits') else 'none'}."
    )
    record: dict[str, Any] = {
        "@context": CONTEXT,
        "@type": "sc:Dataset",
        "conformsTo": CONFORMS_TO,
        "name": store_name,
        "description": description,
        "version": f"{number}.0.0" if number.isdigit() else reader.version,
        "identifier": f"{reader.version}:{manifest.get('fingerprint')}",
        "datePublished": str(manifest.get("created_at", ""))[:10] or None,
        "license": license,
        "citeAs": citation,
        "distribution": distribution,
        "recordSet": record_sets,
    }
    if base_url:
        record["url"] = base_url
    return {k: v for k, v in record.items() if v is not None}


def write_croissant(record: dict[str, Any], out: Path, store: str | Path | None = None) -> Path:
    """Write ``record`` as indented JSON to ``out`` (a new name: never over a folder), never
    inside a version folder of the local ``store``: a committed version holds only the files
    its checksums record, so ``validate`` would report the record as an unrecorded file."""
    if out.is_dir():
        raise StoreError("the Croissant output is a folder; give a file name", out)
    if store is not None and "://" not in str(store):
        versions, target = (Path(store) / "versions").resolve(), out.resolve()
        inside = target.relative_to(versions).parts if target.is_relative_to(versions) else ()
        if len(inside) > 1:
            raise StoreError(
                f"the Croissant record would go inside the store's version folder "
                f"versions/{inside[0]}, which holds only the files recorded at its commit "
                "(validate would report it); write it outside the store, e.g. next to a "
                f"published copy of versions/{inside[0]}/",
                out,
            )
    out.parent.mkdir(parents=True, exist_ok=True)
    tmp = out.with_name(out.name + ".tmp")
    tmp.write_text(json.dumps(record, indent=2) + "\n")
    tmp.replace(out)
    return out
