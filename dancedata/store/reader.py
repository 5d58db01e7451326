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
from dancedata.store.fs import is_remote, zarr_store
from dancedata.store.layout import TABLE_FILES, ZARR_DIR, StoreLayout

if TYPE_CHECKING:
    import pyarrow as pa
    import zarr


class VersionReader:
    """Read-only access to ``STORE/versions/<version>`` (latest when ``version`` is None)."""

    def __init__(self, store: str | Path, version: str | None = None) -> None:
        self.layout = StoreLayout(store)
        self.version = self.layout.resolve(version)
        self.path = self.layout.version_dir(self.version)
        self._tables: dict[str, pa.Table] = {}

    @cached_property
    def manifest(self) -> dict[str, Any]:
        return self.layout.read_manifest(self.version)

    @property
    def remote(self) -> bool:
        return is_remote(str(self.layout.root))

    @cached_property
    def root(self) -> zarr.Group | None:
        import zarr

        if self.remote:
            return self._remote_root()
        path = self.path / ZARR_DIR
        if not path.exists():
            return None
        import warnings

        from zarr.storage import LocalStore

        from dancedata.store.checked_store import CheckedStore

        recorded = functools.partial(recorded_chunks, self.path)  # picklable, read on demand
        store = CheckedStore(LocalStore(str(path), read_only=True), str(path), recorded)
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", category=UserWarning)
            try:
                return zarr.open_group(store=store, mode="r", use_consolidated=True)
            except (ValueError, KeyError, FileNotFoundError):
                return zarr.open_group(store=store, mode="r")

    def _remote_root(self) -> zarr.Group | None:
        import warnings

        import zarr

        from dancedata.store.checked_store import CheckedStore

        location = self.layout.zarr_location(self.version)
        store = CheckedStore(zarr_store(location, read_only=True), str(location))
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
        if self.remote:
            return self.layout.has_file(self.version, TABLE_FILES[name])
        return (self.path / TABLE_FILES[name]).is_file()

    def table(self, name: str) -> pa.Table:
        if name not in TABLE_FILES:
            raise StoreError(f"unknown table {name!r}; known: {sorted(TABLE_FILES)}")
        if name not in self._tables:
            import pyarrow.parquet as pq

            if self.remote:
                self._tables[name] = self._remote_table(name)
                return self._tables[name]
            path = self.path / TABLE_FILES[name]
            if not path.is_file():
                raise StoreError(f"version {self.version} has no {name} table", self.path)
            try:
                self._tables[name] = pq.read_table(path)
            except Exception as exc:  # pyarrow raises ArrowInvalid, OSError, ...
                raise StoreError(f"unreadable table: {exc}", path) from None
        return self._tables[name]

    def _remote_table(self, name: str) -> pa.Table:
        import io

        import pyarrow.parquet as pq

        where = f"{self.path}/{TABLE_FILES[name]}"
        try:
            data = self.layout.read_bytes(self.version, TABLE_FILES[name])
        except FileNotFoundError:
            raise StoreError(f"version {self.version} has no {name} table", where) from None
        try:
            return pq.read_table(io.BytesIO(data))
        except Exception as exc:  # pyarrow raises ArrowInvalid, OSError, ...
            raise StoreError(f"unreadable table: {exc}", where) from None

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


def recorded_chunks(version_dir: Path) -> dict[str, Any]:
    """checksums.json entries of a local version's data.zarr files, keyed by their path inside
    data.zarr (what the checking store needs for arrays written without crc32c); {} when the
    version has no readable record."""
    from dancedata.store.integrity import load_record

    record = load_record(Path(version_dir)) or {}
    files = record.get("files")
    if not isinstance(files, dict):
        return {}
    prefix = f"{ZARR_DIR}/"
    return {
        rel[len(prefix) :]: entry
        for rel, entry in files.items()
        if rel.startswith(prefix) and isinstance(entry, dict)
    }
