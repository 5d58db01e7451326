"""Read one committed version: manifest, parquet tables, zarr arrays and group attrs.

Arrays are read through :class:`dancedata.store.checked_store.CheckedStore`: a chunk that is
missing or corrupted raises StoreError naming the version's data.zarr, the array and the chunk,
instead of reading as fill values or wrong numbers (crc32c for arrays written with it; the
sha256 recorded in checksums.json for arrays written before).
"""

from __future__ import annotations

import functools
from functools import cached_property
from pathlib import Path
from typing import TYPE_CHECKING, Any

from dancedata.errors import StoreError
from dancedata.store.backend import StoreBackend
from dancedata.store.backend_open import make_backend
from dancedata.store.layout import TABLE_FILES, ZARR_DIR, StoreLayout
from dancedata.store.metadata_checks import array_meta_problem, group_attrs_problem, table_problem
from dancedata.store.untrusted import TABLE_LIMIT, ZARR_JSON_LIMIT, read_json

if TYPE_CHECKING:
    import pyarrow as pa
    import zarr


class _VersionReader:
    """Read-only access to ``STORE/versions/<version>`` (latest when ``version`` is None), on
    any backend: the store layer's reader, private (users read through
    :class:`dancedata.read.loader.DanceStore`, which holds one)."""

    def __init__(
        self, store: str | Path | StoreBackend | StoreLayout, version: str | None = None
    ) -> None:
        self.layout = store if isinstance(store, StoreLayout) else StoreLayout(store)
        self.version = self.layout.resolve(version)
        self.path = self.layout.version_dir(self.version)  # a Path locally, else a URL
        self.files = self.layout.version_backend(self.version)
        self._tables: dict[str, pa.Table] = {}
        check_regular_tree(self.files, self.path)

    @cached_property
    def manifest(self) -> dict[str, Any]:
        return self.layout.read_manifest(self.version)

    @cached_property
    def root(self) -> zarr.Group | None:
        import warnings

        import zarr

        from dancedata.store.checked_store import CheckedStore

        if not self.files.is_dir(ZARR_DIR):
            return None
        check_zarr_metadata(self.files)
        recorded = functools.partial(recorded_chunks, self.files)  # picklable, read on demand
        store = CheckedStore(
            self.files.zarr_store(ZARR_DIR, read_only=True),
            str(self.files.where(ZARR_DIR)),
            recorded,
        )
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", category=UserWarning)
            try:
                return zarr.open_group(store=store, mode="r", use_consolidated=True)
            except (ValueError, KeyError, FileNotFoundError):
                try:
                    return zarr.open_group(store=store, mode="r")
                except FileNotFoundError:
                    return None

    def has_table(self, name: str) -> bool:
        return self.files.is_file(TABLE_FILES[name])

    def table(self, name: str) -> pa.Table:
        if name not in TABLE_FILES:
            raise StoreError(f"unknown table {name!r}; known: {sorted(TABLE_FILES)}")
        if name not in self._tables:
            where = self.files.where(TABLE_FILES[name])
            try:
                data = self.files.read_small(TABLE_FILES[name], TABLE_LIMIT)
            except (FileNotFoundError, IsADirectoryError):
                raise StoreError(f"version {self.version} has no {name} table", where) from None
            except OSError as exc:
                raise StoreError(f"unreadable table: {exc.strerror or exc}", where) from None
            problem = parquet_size_problem(data)
            if problem is not None:
                raise StoreError(f"{name} table: {problem}", where)
            try:
                table = parquet_table(data)
            except Exception as exc:  # pyarrow raises ArrowInvalid, OSError, ...
                raise StoreError(f"unreadable table: {str(exc)[:300]}", where) from None
            problem = table_problem(name, table)
            if problem is not None:
                raise StoreError(f"{name} table: {problem}", where)
            self._tables[name] = table
        return self._tables[name]

    def _array_node(self, name: str) -> zarr.Array | None:
        """The array at ``name`` in data.zarr, None when there is none (or a group is there)."""
        root = self.root
        if root is None:
            return None
        try:
            node = root[name]
        except KeyError:
            return None
        import zarr

        return node if isinstance(node, zarr.Array) else None

    def has_array(self, name: str) -> bool:
        return self._array_node(name) is not None

    def array(self, name: str) -> zarr.Array:
        node = self._array_node(name)  # one lookup: each costs a metadata read through zarr
        if node is None:
            import difflib

            close = difflib.get_close_matches(name, self.array_names(), n=3, cutoff=0.8)
            hint = f"did you mean {', '.join(map(repr, close))}?" if close else "run featurize?"
            raise StoreError(f"version {self.version} has no array {name!r} ({hint})", self.path)
        return node

    def array_names(self) -> list[str]:
        """Every array path in data.zarr, e.g. ``motion/trans``, sorted."""
        root = self.root
        if root is None:
            return []
        import zarr

        names: list[str] = []

        def walk(group: zarr.Group, prefix: str) -> None:
            for key, node in group.members():
                path = f"{prefix}{key}"
                if isinstance(node, zarr.Group):
                    walk(node, path + "/")
                else:
                    names.append(path)

        walk(root, "")
        return sorted(names)

    def group_attrs(self, name: str) -> dict[str, Any]:
        root = self.root
        if root is None:
            return {}
        try:
            return dict(root[name].attrs)
        except KeyError:
            return {}


def recorded_chunks(version_dir: str | Path | StoreBackend) -> dict[str, Any]:
    """checksums.json entries of a version's data.zarr files, keyed by their path inside
    data.zarr (what the checking store needs for arrays written without crc32c); {} when the
    version has no readable record."""
    from dancedata.store.integrity import load_record

    record = load_record(make_backend(version_dir)) or {}
    files = record.get("files")
    if not isinstance(files, dict):
        return {}
    prefix = f"{ZARR_DIR}/"
    return {
        rel[len(prefix) :]: entry
        for rel, entry in files.items()
        if rel.startswith(prefix) and isinstance(entry, dict)
    }


# A table is decoded whole: its footer's row and column counts are checked first (a few kB of
# run-length encoded zeros can decode to gigabytes).
MAX_TABLE_ROWS = 50_000_000
MAX_TABLE_DECODED = 512 * 1024 * 1024


def parquet_table(data: bytes) -> pa.Table:
    """The table of a Parquet file's bytes, decoded on this thread without starting any of
    pyarrow's native threads. A process that exits while such a thread is alive can abort at
    exit ("terminate called without an active exception", SIGABRT; apache/arrow#34314):
    ``read_table`` over io.BytesIO did so in about one run in three; ``read_table`` over an
    Arrow buffer with ``use_threads=False`` still started a scanner thread, and did so in about
    1 run in 40 (2 in 40 with every numeric thread pool pinned to one thread).
    ``ParquetFile.read`` starts none (0 in 60). The tables are small. It does not import
    pandas either (a writer does, before it locks: ``store.writer.import_before_locking``)."""
    import pyarrow as pa
    import pyarrow.parquet as pq

    return pq.ParquetFile(pa.BufferReader(data)).read(use_threads=False)


def parquet_size_problem(data: bytes) -> str | None:
    """Why a Parquet file must not be decoded (its footer declares more rows or decoded bytes
    than a table of a store can need), or None. An unreadable footer is left to the reader."""
    import pyarrow as pa
    import pyarrow.parquet as pq

    try:
        meta = pq.read_metadata(pa.BufferReader(data))
    except Exception:  # pyarrow raises ArrowInvalid, OSError, ...: read_table names it
        return None
    if meta.num_rows > MAX_TABLE_ROWS:
        return f"declares {meta.num_rows:,} rows, over the limit of {MAX_TABLE_ROWS:,} (not read)"
    # the footer's byte counts describe the encoded pages (a run of zeros is a few bytes);
    # what decoding allocates is about 8 bytes per cell (more for strings)
    cells = meta.num_rows * max(1, meta.num_columns)
    if cells * 8 > MAX_TABLE_DECODED:
        return (
            f"declares {meta.num_rows:,} rows × {meta.num_columns} columns, about "
            f"{cells * 8:,} bytes decoded, over the limit of {MAX_TABLE_DECODED:,} (not read)"
        )
    return None


def check_regular_tree(files: StoreBackend, where: Any) -> None:
    """StoreError naming the first entry of a version folder that is a symbolic link, a FIFO,
    a device or a socket: a store holds regular files and folders only, and readers never read
    through anything else (zarr opens chunk files by path)."""
    found = files.special_below("")
    if found:
        rel, kind = found[0]
        more = f" ({len(found) - 1} more such entries)" if len(found) > 1 else ""
        raise StoreError(
            f"{rel} is {kind} in {files.name}, not a regular file (a store holds regular files "
            f"only; nothing is read through it){more}",
            where,
        )


def _metadata_nodes(files: StoreBackend) -> list[str]:
    """Paths inside data.zarr of every zarr.json that is node metadata (not inside a chunk
    folder)."""
    nodes = []
    for rel in files.find(ZARR_DIR):
        parts = rel.split("/")
        if parts[-1] == "zarr.json" and "c" not in parts[:-1]:
            nodes.append("/".join(parts[:-1]))
    return sorted(nodes)


def metadata_problems(files: StoreBackend, *, limit: int | None = None) -> list[str]:
    """One line per zarr.json of a version's data.zarr (and per node of the consolidated
    metadata of its root) that cannot be trusted: not JSON, too large or deep, or declaring an
    array or attributes outside :mod:`dancedata.store.metadata_checks`' bounds. Stops after
    ``limit`` problems."""
    problems: list[str] = []

    def check(node: str, meta: Any, where: Any) -> None:
        problem = array_meta_problem(meta)
        if problem is None and isinstance(meta, dict):
            problem = group_attrs_problem(node, meta.get("attributes", {}))
        if problem is not None:
            problems.append(f"{where}: {problem}")

    for node in _metadata_nodes(files):
        if limit is not None and len(problems) >= limit:
            break
        key = f"{ZARR_DIR}/{node}/zarr.json" if node else f"{ZARR_DIR}/zarr.json"
        try:
            meta = read_json(files, key, limit=ZARR_JSON_LIMIT, what="zarr.json")
        except FileNotFoundError:
            continue
        except StoreError as exc:
            problems.append(str(exc))
            continue
        check(node, meta, files.where(key))
        consolidated = meta.get("consolidated_metadata") if isinstance(meta, dict) else None
        if not node and isinstance(consolidated, dict):
            entries = consolidated.get("metadata")
            if not isinstance(entries, dict):
                problems.append(f"{files.where(key)}: consolidated metadata is not an object")
                continue
            for inner, inner_meta in sorted(entries.items()):
                if limit is not None and len(problems) >= limit:
                    break
                check(inner, inner_meta, f"{files.where(key)} (consolidated entry {inner!r:.60})")
    return problems


def check_zarr_metadata(files: StoreBackend) -> None:
    """StoreError naming the file of the first problem :func:`metadata_problems` finds (before
    zarr parses any of it)."""
    problems = metadata_problems(files, limit=1)
    if problems:
        raise StoreError(problems[0])
