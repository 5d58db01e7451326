"""A read-only zarr store that refuses to return a chunk that is missing, fails its crc32c, or
differs from the sha256 in ``checksums.json`` (see :mod:`dancedata.store.chunks` for the rules).

Every chunk read goes through :meth:`CheckedStore.get`, whatever the access path (slicing,
``np.asarray``, orthogonal selection), so no reader of a version can get fill values or flipped
bytes in place of its data; the error names the version's ``data.zarr``, the array and the
chunk key. Defined at module level so that a store (and an array opened on it) can be pickled.
"""

from __future__ import annotations

import hashlib
import os
import stat
from collections.abc import Callable
from typing import Any

from zarr.abc.store import ByteRequest, Store
from zarr.core.buffer import Buffer, BufferPrototype
from zarr.storage import LocalStore, WrapperStore

from dancedata.errors import StoreError
from dancedata.store.chunks import (
    ChunkGrid,
    crc32c_matches,
    decoded_size_problem,
    describe_chunk,
    split_chunk_key,
)
from dancedata.store.metadata_checks import array_meta_problem
from dancedata.store.untrusted import ZARR_JSON_LIMIT, not_regular, parse_json, too_large


class CheckedStore(WrapperStore):  # type: ignore[type-arg]
    """``store`` (the data.zarr of one version, named ``where`` in messages), checked on read.

    ``recorded`` returns the version's ``checksums.json`` entries of data.zarr files keyed by
    their path inside data.zarr (``motion/trans/c/0/0``); it is called at most once, the first
    time a chunk of an array without crc32c is read, and may return {} (no record).
    """

    def __init__(
        self,
        store: Store,
        where: str = "",
        recorded: Callable[[], dict[str, Any]] | None = None,
    ) -> None:
        super().__init__(store)
        self.where = where
        self.recorded = recorded
        self._grids: dict[str, ChunkGrid | None] = {}
        self._record: dict[str, Any] | None = None

    def _with_store(self, store: Store) -> CheckedStore:
        return CheckedStore(store, self.where, self.recorded)

    def __getstate__(self) -> dict[str, Any]:
        return {"store": self._store, "where": self.where, "recorded": self.recorded}

    def __setstate__(self, state: dict[str, Any]) -> None:
        self.__init__(state["store"], state["where"], state["recorded"])  # type: ignore[misc]

    async def _grid(self, array: str, prototype: BufferPrototype) -> ChunkGrid | None:
        if array not in self._grids:
            meta_key = f"{array}/zarr.json" if array else "zarr.json"
            self._check_regular(meta_key)
            raw = await self._store.get(meta_key, prototype)
            meta = None
            if raw is not None:
                data = raw.to_bytes()
                where = f"{self.where}/{meta_key}" if self.where else meta_key
                if len(data) > ZARR_JSON_LIMIT:
                    raise StoreError(str(too_large(where, len(data), ZARR_JSON_LIMIT)))
                meta = parse_json(data, where, "zarr.json")
                problem = array_meta_problem(meta)
                if problem is not None:
                    raise StoreError(problem, where)
            self._grids[array] = ChunkGrid.from_metadata(meta)
        return self._grids[array]

    def _recorded(self) -> dict[str, Any]:
        if self._record is None:
            self._record = (self.recorded() if self.recorded else None) or {}
        return self._record

    def _fail(self, array: str, chunk: str, problem: str) -> StoreError:
        return StoreError(f"{describe_chunk(array, chunk)}: {problem}", self.where or None)

    async def get(
        self,
        key: str,
        prototype: BufferPrototype,
        byte_range: ByteRequest | None = None,
    ) -> Buffer | None:
        self._check_regular(key)
        value = await self._store.get(key, prototype, byte_range)
        split = split_chunk_key(key)
        if split is None or byte_range is not None:
            return value
        array, chunk = split
        grid = await self._grid(array, prototype)
        if grid is None:
            return value
        coords = grid.coords(chunk)
        if coords is None or not grid.in_grid(coords):
            return value
        if grid.crc32c:
            if value is None:
                raise self._fail(
                    array,
                    chunk,
                    "missing (every chunk of this array was written; reading it would return "
                    "fill values)",
                )
            if not crc32c_matches(value.as_numpy_array()):
                raise self._fail(array, chunk, "crc32c checksum mismatch (the chunk is corrupted)")
            self._check_size(grid, array, chunk, value)
            return value
        entry = self._recorded().get(key)
        if entry is None:
            return value
        if value is None:
            raise self._fail(
                array,
                chunk,
                "missing, but checksums.json recorded it at commit (reading it would return "
                "fill values)",
            )
        if hashlib.sha256(value.as_numpy_array()).hexdigest() != entry.get("sha256"):
            raise self._fail(
                array, chunk, "sha256 differs from checksums.json (the chunk is corrupted)"
            )
        self._check_size(grid, array, chunk, value)
        return value

    def _check_size(self, grid: ChunkGrid, array: str, chunk: str, value: Buffer) -> None:
        problem = decoded_size_problem(grid, value.as_numpy_array())
        if problem is not None:
            raise self._fail(array, chunk, problem)

    def _check_regular(self, key: str) -> None:
        """Refuse a file that is a symbolic link, a FIFO or a device before zarr opens it (a
        local store: zarr opens files by path, and a FIFO would block forever)."""
        root = getattr(self._store, "root", None)
        if root is None or not isinstance(self._store, LocalStore):
            return
        path = os.path.join(str(root), key)
        try:
            mode = os.lstat(path).st_mode
        except OSError:
            return
        if not stat.S_ISREG(mode):
            raise StoreError(str(not_regular(path, mode)))
