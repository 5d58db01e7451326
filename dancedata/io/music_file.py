"""A music file's identity on disk: its stamp (size, modification time) and its sha256.

Ingest records both for every track (music table columns ``size_bytes``, ``mtime_ns`` and
``sha256``). featurize checks a file against them before using it: an unchanged stamp is the
fast path (no read); a changed stamp means the file is read and hashed, and only a different
hash means the content changed. Hashing reads the file through an open handle in 1 MiB blocks
(bounded memory), so a caller can hash and decode the very same open file.
"""

from __future__ import annotations

import hashlib
import os
from dataclasses import dataclass
from pathlib import Path
from typing import BinaryIO

HASH_BLOCK_BYTES = 1 << 20


@dataclass(frozen=True)
class FileStamp:
    """Size in bytes and modification time in integer nanoseconds (``st_mtime_ns``)."""

    size_bytes: int
    mtime_ns: int

    @classmethod
    def of(cls, stat: os.stat_result) -> FileStamp:
        return cls(int(stat.st_size), int(stat.st_mtime_ns))

    @classmethod
    def recorded(cls, size_bytes: object, mtime_ns: object) -> FileStamp | None:
        """The stamp a table row records, or None when the row predates stamps."""
        if size_bytes is None or mtime_ns is None:
            return None
        return cls(int(size_bytes), int(mtime_ns))  # type: ignore[call-overload]

    def columns(self) -> dict[str, int]:
        """The music table columns of this stamp."""
        return {"size_bytes": self.size_bytes, "mtime_ns": self.mtime_ns}


def file_stamp(path: str | Path) -> FileStamp:
    """The stamp of ``path`` now (follows symlinks, as opening it does)."""
    return FileStamp.of(os.stat(path))


def sha256_of_handle(handle: BinaryIO) -> str:
    """Hex sha256 of everything in the open binary ``handle``, read from its start; the handle
    is left at its start again."""
    digest = hashlib.sha256()
    handle.seek(0)
    while block := handle.read(HASH_BLOCK_BYTES):
        digest.update(block)
    handle.seek(0)
    return digest.hexdigest()


def sha256_of_path(path: str | Path) -> str:
    """Hex sha256 of the file at ``path`` (streamed, bounded memory)."""
    with open(path, "rb") as handle:
        return sha256_of_handle(handle)
