"""Which chunk files a zarr v3 array must have, and how to tell a chunk is intact (the reading
side is :class:`dancedata.store.checked_store.CheckedStore`).

Every array dancedata writes carries zarr v3's standard ``crc32c`` codec last in its codec
chain (4 bytes of CRC-32C appended to each compressed chunk) and is written with
``write_empty_chunks``, so each chunk of its grid exists as a file. A reader can therefore
refuse:

* a chunk whose bytes no longer match their crc32c (bit rot, a flipped byte), and
* a chunk that is absent (zarr would silently return the fill value: zeros).

Arrays written before this (no crc32c codec) may legitimately lack all-zero chunks (zarr skips
writing chunks equal to the fill value); for them a chunk is required when the version's
``checksums.json`` lists it, and when it does, its sha256 is checked on read instead.
"""

from __future__ import annotations

import itertools
import math
from collections.abc import Iterator
from dataclasses import dataclass
from typing import Any, cast

CRC32C_CODEC = "crc32c"


@dataclass(frozen=True)
class ChunkGrid:
    """The regular chunk grid of one zarr v3 array, from its ``zarr.json``."""

    shape: tuple[int, ...]
    chunk_shape: tuple[int, ...]
    separator: str  # chunk key separator: "/" (c/0/0) or "." (c.0.0)
    default_encoding: bool  # "default" (c/ prefix) or "v2" (bare 0.0) encoding
    crc32c: bool  # the codec chain ends with crc32c: every chunk was written and is checked
    chunk_bytes: int = 0  # bytes of one decoded chunk (0: unknown)
    codecs: tuple[str, ...] = ()  # codec names, in order

    @classmethod
    def from_metadata(cls, meta: Any) -> ChunkGrid | None:
        """The grid of an array's parsed ``zarr.json``; None for a group or anything that is not
        a regular-grid zarr v3 array (those are not checked here)."""
        if not isinstance(meta, dict) or meta.get("node_type") != "array":
            return None
        from dancedata.store.metadata_checks import array_meta_problem

        if array_meta_problem(meta) is not None:
            return None  # refused by the reader and reported by validate, never enumerated
        try:
            shape = tuple(int(n) for n in meta["shape"])
            grid = meta["chunk_grid"]
            if grid.get("name") != "regular":
                return None
            chunk_shape = tuple(int(n) for n in grid["configuration"]["chunk_shape"])
            encoding = meta.get("chunk_key_encoding") or {"name": "default"}
            name = encoding.get("name", "default")
            default_sep = "/" if name == "default" else "."
            separator = (encoding.get("configuration") or {}).get("separator", default_sep)
            codecs = meta.get("codecs") or []
            crc = (
                bool(codecs)
                and isinstance(codecs[-1], dict)
                and (codecs[-1].get("name") == CRC32C_CODEC)
            )
        except (KeyError, TypeError, ValueError, AttributeError):
            return None
        if len(shape) != len(chunk_shape) or any(c <= 0 for c in chunk_shape):
            return None
        from dancedata.store.metadata_checks import decoded_chunk_bytes

        # array_meta_problem passed: every codec is a known name or a dict with one (a str)
        names = tuple(cast(str, c.get("name")) if isinstance(c, dict) else str(c) for c in codecs)
        return cls(
            shape, chunk_shape, separator, name == "default", crc, decoded_chunk_bytes(meta), names
        )

    @property
    def n_chunks(self) -> int:
        """Chunks the shape and chunk grid call for (computed, never enumerated)."""
        return math.prod(self.grid_shape)

    @property
    def grid_shape(self) -> tuple[int, ...]:
        """Chunks along each axis (0 for an empty axis)."""
        return tuple(math.ceil(n / c) for n, c in zip(self.shape, self.chunk_shape, strict=True))

    def key(self, coords: tuple[int, ...]) -> str:
        """The chunk key of ``coords`` relative to the array, e.g. ``c/3/0/0``."""
        parts = [str(i) for i in coords] or ["0"]
        body = self.separator.join(parts)
        return f"c{self.separator}{body}" if self.default_encoding else body

    def chunk_keys(self) -> Iterator[str]:
        """Every chunk key the array's shape and chunk grid call for."""
        for coords in itertools.product(*(range(n) for n in self.grid_shape)):
            yield self.key(coords)

    def coords(self, key: str) -> tuple[int, ...] | None:
        """The chunk coordinates of an array-relative key, or None when it is not a chunk key."""
        body = key
        if self.default_encoding:
            prefix = f"c{self.separator}"
            if key == "c" and not self.shape:
                return ()
            if not key.startswith(prefix):
                return None
            body = key[len(prefix) :]
        parts = body.split(self.separator)
        if not all(p.isdigit() for p in parts) or len(parts) != max(1, len(self.shape)):
            return None
        coords = tuple(int(p) for p in parts)
        return coords if self.shape else ()

    def in_grid(self, coords: tuple[int, ...]) -> bool:
        return all(0 <= i < n for i, n in zip(coords, self.grid_shape, strict=False))


def split_chunk_key(key: str) -> tuple[str, str] | None:
    """``motion/rotmat/c/0/0/0/0`` → (``motion/rotmat``, ``c/0/0/0/0``): the array path and the
    array-relative chunk key (default encoding); None for metadata and other keys."""
    parts = key.split("/")
    index = len(parts)
    while index > 0 and parts[index - 1].isdigit():
        index -= 1
    if index == len(parts) or index == 0 or parts[index - 1] != "c":
        return None
    return "/".join(parts[: index - 1]), "/".join(parts[index - 1 :])


def describe_chunk(array: str, chunk_key: str) -> str:
    """``array motion/trans chunk c/0/0`` for messages."""
    return f"array {array or '/'} chunk {chunk_key}"


def crc32c_matches(data: Any) -> bool:
    """True when the last 4 bytes of ``data`` are the little-endian CRC-32C of the rest (the
    layout of zarr v3's crc32c codec)."""
    import google_crc32c
    import numpy as np

    raw = np.frombuffer(data, dtype=np.uint8)
    if raw.shape[0] < 4:
        return False
    computed = np.uint32(google_crc32c.value(np.ascontiguousarray(raw[:-4]))).tobytes()
    return computed == raw[-4:].tobytes()


def zstd_content_size(frame: Any) -> int | None:
    """The decoded size a zstd frame declares in its header (Frame_Content_Size), or None
    when the bytes are not a zstd frame or the header leaves the size out (RFC 8878 §3.1.1)."""
    import numpy as np

    raw = np.frombuffer(frame, dtype=np.uint8)
    if raw.shape[0] < 5 or raw[:4].tobytes() != b"\x28\xb5\x2f\xfd":
        return None
    descriptor = int(raw[4])
    fcs_flag, single_segment, dict_flag = descriptor >> 6, (descriptor >> 5) & 1, descriptor & 3
    offset = 5 + (0 if single_segment else 1) + (0, 1, 2, 4)[dict_flag]
    width = (1 if single_segment else 0, 2, 4, 8)[fcs_flag]
    if width == 0 or raw.shape[0] < offset + width:
        return None
    value = int.from_bytes(raw[offset : offset + width].tobytes(), "little")
    return value + 256 if width == 2 else value


def blosc_content_size(frame: Any) -> int | None:
    """The decoded size a blosc frame declares (bytes 4-7 of its 16-byte header), or None when
    the bytes are not one blosc frame (a header whose version is not 1-4, or whose compressed
    size, bytes 12-15, is not the frame's length)."""
    import numpy as np

    raw = np.frombuffer(frame, dtype=np.uint8)
    if raw.shape[0] < 16 or not 1 <= int(raw[0]) <= 4:
        return None
    if int.from_bytes(raw[12:16].tobytes(), "little") != raw.shape[0]:
        return None
    return int.from_bytes(raw[4:8].tobytes(), "little")


def decoded_size_problem(grid: ChunkGrid, data: Any) -> str | None:
    """Why a stored chunk must not be decoded: its compressor's header declares more bytes than
    one chunk of the array holds (a decompression bomb), or declares none. Checked before zarr
    allocates the decoded buffer. ``data`` is the stored chunk (crc32c suffix included)."""
    if not grid.chunk_bytes:
        return None
    body = data[:-4] if grid.crc32c else data
    for name, size_of in (("zstd", zstd_content_size), ("blosc", blosc_content_size)):
        if name in grid.codecs:
            declared = size_of(body)
            if declared is None:
                return (
                    f"not a {name} frame with a declared decoded size (refused before decoding: "
                    "it could be any size, or not decode at all)"
                )
            if declared > grid.chunk_bytes:
                return (
                    f"its {name} header declares {declared:,} decoded bytes, but a chunk of this "
                    f"array holds {grid.chunk_bytes:,} (refused before decoding)"
                )
            return None
    return None
