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

if TYPE_CHECKING:
    import pyarrow as pa
    import zarr


class VersionReader:
    """Read-only access to ``STORE/versions/<version>`` (latest when ``version`` is None), on
    any backend."""

    def __init__(self, store: str | Path | StoreBackend, version: str | None = None) -> None:
        self.layout = StoreLayout(store)
        self.version = self.layout.resolve(version)
        self.path = self.layout.version_dir(self.version)  # a Path locally, else a URL
        self.files = self.layout.version_backend(self.version)
        self._tables: dict[str, pa.Table] = {}

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
        recorded = functools.partial(recorded_chunks, self.files)  # picklable, read on demand
        store = CheckedStore(
            self.files.zarr_store(ZARR_DIR, read_only=True), str(self.files.where(ZARR_DIR)),
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
            import pyarrow as pa
            import pyarrow.parquet as pq

            where = self.files.where(TABLE_FILES[name])
            try:
                data = self.files.read_bytes(TABLE_FILES[name])
            except (FileNotFoundError, IsADirectoryError):
                raise StoreError(f"version {self.version} has no {name} table", where) from None
            except OSError as exc:
                raise StoreError(f"unreadable table: {exc}", where) from None
            try:
                # An Arrow buffer read on this thread: with io.BytesIO (read from pyarrow's IO
                # threads) a process exiting after the read aborted in about one run in three
                # ("terminate called without an active exception", SIGABRT), and with pyarrow's
                # decoding threads still in about 1 in 40. The tables are small.
                self._tables[name] = pq.read_table(pa.BufferReader(data), use_threads=False)
            except Exception as exc:  # pyarrow raises ArrowInvalid, OSError, ...
                raise StoreError(f"unreadable table: {exc}", where) from None
        return self._tables[name]

    def has_array(self, name: str) -> bool:
        root = self.root
        if root is None:
            return False
        try:
            node = root[name]
        except KeyError:
            return False
        import zarr

        return isinstance(node, zarr.Array)

    def array(self, name: str) -> zarr.Array:
        if not self.has_array(name):
            raise StoreError(
                f"version {self.version} has no array {name!r} (run featurize?)", self.path
            )
        return self.root[name]  # type: ignore[index]

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
