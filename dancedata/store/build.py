"""The scratch area of a version being built: what workers write and what a resumed run finds.

A :class:`BuildArea` names the temporary version directory (local path or remote URL) and is
plain data, so it travels to worker processes and Dask workers. Inside it, ``.build/`` holds
build state that never reaches a committed version:

    .build/prepared.json              the version's arrays exist, pre-sized (written once)
    .build/units/<kind>/<unit>.json   unit finished: its outputs are complete and durable
    .build/out/<kind>/<unit>/*.npy    per-unit outputs that the driver packs afterwards

Every marker is written after the outputs it vouches for, by write-then-rename locally and by
a single PUT on object stores (both atomic), so a marker never names a partial output.
"""

from __future__ import annotations

import io
from dataclasses import dataclass
from functools import lru_cache
from typing import Any

import numpy as np

from dancedata.errors import StoreError
from dancedata.store.backend import StoreBackend, json_bytes
from dancedata.store.backend_open import make_backend
from dancedata.store.layout import ZARR_DIR

BUILD_DIR = ".build"
PREPARED_FILE = "prepared.json"


@lru_cache(maxsize=16)
def _backend_of(root: str) -> StoreBackend:
    return make_backend(root)


@dataclass(frozen=True)
class BuildArea:
    """The temporary directory (or prefix) of one version in the making."""

    root: str

    @property
    def backend(self) -> StoreBackend:
        """The storage of this area (rooted at the temporary version)."""
        return _backend_of(self.root)

    def _key(self, rel: str) -> str:
        return f"{BUILD_DIR}/{rel}"

    # -- zarr ----------------------------------------------------------------------------------
    def zarr_location(self) -> str:
        return f"{self.root.rstrip('/')}/{ZARR_DIR}"

    def open_array(self, name: str) -> Any:
        """The version's array ``name`` (e.g. ``motion/rotmat``), open for writing regions."""
        return _open_array(self.root, name)

    # -- small JSON records --------------------------------------------------------------------
    def write_json(self, rel: str, value: Any) -> None:
        """Write ``.build/<rel>`` atomically (rename locally, one PUT remotely)."""
        self.backend.write_bytes(self._key(rel), json_bytes(value))

    def read_json(self, rel: str) -> Any | None:
        """``.build/<rel>`` parsed, or None when absent or unreadable (a torn write)."""
        from dancedata.store.untrusted import BUILD_JSON_LIMIT, parse_json

        try:
            data = self.backend.read_small(self._key(rel), BUILD_JSON_LIMIT)
            return parse_json(data, self._key(rel), rel)
        except (OSError, StoreError):
            return None

    def read_all_json(self, rel_dir: str) -> dict[str, Any]:
        """Every ``.build/<rel_dir>/<name>.json``, keyed by name (unreadable ones left out)."""
        found: dict[str, Any] = {}
        for name in self.backend.list_dir(self._key(rel_dir)):
            if name.endswith(".json") and not name.startswith("."):
                value = self.read_json(f"{rel_dir}/{name}")
                if value is not None:
                    found[name[: -len(".json")]] = value
        return found

    # -- array outputs -------------------------------------------------------------------------
    def save_array(self, rel: str, values: np.ndarray) -> None:
        """Write ``.build/<rel>`` as .npy (the unit's marker, written later, vouches for it)."""
        buffer = io.BytesIO()
        np.save(buffer, values, allow_pickle=False)
        self.backend.write_bytes(self._key(rel), buffer.getbuffer(), durable=False)

    def load_array(self, rel: str) -> np.ndarray:
        return np.load(io.BytesIO(self.backend.read_bytes(self._key(rel))), allow_pickle=False)

    def save_blob(self, rel: str, arrays: dict[str, np.ndarray]) -> dict[str, list[Any]]:
        """Write several arrays back to back as one raw file ``.build/<rel>`` (no compression,
        no zip, no CRC: this is scratch data) and return its index, {key: [offset, dtype,
        shape]}, for the unit's marker. Numeric and bool dtypes only (never objects)."""
        index: dict[str, list[Any]] = {}
        parts: list[np.ndarray] = []
        offset = 0
        for key, value in arrays.items():
            value = np.asarray(value)
            if not value.flags.c_contiguous:  # (ascontiguousarray would make 0-d arrays 1-d)
                value = value.copy(order="C")
            if value.dtype.hasobject:
                raise TypeError(f"{key}: object arrays cannot be saved")
            index[key] = [offset, value.dtype.str, list(value.shape)]
            parts.append(value)
            offset += value.nbytes + (-value.nbytes) % 64  # 64-byte aligned starts
        pieces = [piece for part in parts for piece in _chunks(part)]
        self.backend.write_bytes(self._key(rel), pieces, durable=False)
        return index

    def load_blob(self, rel: str, index: dict[str, list[Any]]) -> dict[str, np.ndarray]:
        """The arrays of a blob written by :meth:`save_blob`; local files are memory-mapped
        (read-only views, no copy), remote ones read in one request."""
        if not index:
            return {}
        raw = np.frombuffer(self.backend.read_buffer(self._key(rel)), dtype=np.uint8)
        out: dict[str, np.ndarray] = {}
        for key, (offset, dtype, shape) in index.items():
            dt = np.dtype(dtype)
            count = int(np.prod(shape, dtype=np.int64))
            out[key] = raw[offset : offset + count * dt.itemsize].view(dt).reshape(shape)
        return out

    def remove(self, rel: str) -> None:
        """Delete ``.build/<rel>`` (file or folder) if present."""
        self.backend.delete(self._key(rel))


@lru_cache(maxsize=64)
def _open_array(root: str, name: str) -> Any:
    """One open array per process and name: opening reads its metadata, so do it once."""
    import zarr

    from dancedata.store.arrays import for_writing  # every chunk written, zeros included

    store = _backend_of(root).zarr_store(ZARR_DIR)
    return for_writing(zarr.open_array(store=store, path=name, mode="r+", zarr_format=3))


def _chunks(values: np.ndarray) -> list[bytes | memoryview]:
    """The array's bytes (no copy), then zeros up to a multiple of 64."""
    pieces: list[bytes | memoryview] = []
    if values.nbytes:
        pieces.append(values.reshape(-1).data.cast("B"))  # .data: memoryview(values)
    pad = (-values.nbytes) % 64
    if pad:
        pieces.append(bytes(pad))
    return pieces
