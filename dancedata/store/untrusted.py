"""A store is untrusted input: the one place its files are opened and its JSON parsed.

Stores travel between people, so every reader assumes a file may be hostile:

* **Only regular files are opened** (:func:`open_regular`): ``O_NOFOLLOW`` refuses a symbolic
  link as the last component and ``O_NONBLOCK`` lets a FIFO open without waiting for a writer;
  ``fstat`` then refuses anything that is not a regular file (FIFO, device, socket, folder).
  Links in the middle of a path are found by :func:`special_entries`, which readers run over a
  version folder when they open it.
* **JSON is read with a size limit and a depth limit** (:func:`read_json`, :func:`parse_json`):
  a file larger than its limit is refused from its ``lstat``/``fstat`` size without reading it,
  at most ``limit + 1`` bytes are ever read, and nesting deeper than :data:`JSON_MAX_DEPTH` is
  refused (``json.loads`` would raise RecursionError on very deep input, and build the whole
  structure first on moderately deep input).

Every refusal is a :class:`UnsafeFile` (an ``OSError``, so callers that turn read failures into
one-line errors naming the file keep doing so) or a :class:`~dancedata.errors.StoreError` naming
the file.
"""

from __future__ import annotations

import errno
import json
import os
import stat
from pathlib import Path
from typing import Any

from dancedata.errors import StoreError

# Nesting of every JSON file a store holds: dancedata writes at most 8 levels (manifest config
# tables, consolidated zarr metadata).
JSON_MAX_DEPTH = 64
# Values (container items) of one JSON file, counted from its commas and brackets before parsing:
# a parsed value costs 50-100 bytes whatever its text, so 30 MB of "[]," (10 million lists, under
# the manifest's size limit) took 1.5 GB and 90 s. 4 million values parse in about 300 MB; a
# checksums.json spends 3 per file (1.3 million files), a manifest 5-10 per input.
JSON_MAX_VALUES = 4_000_000

# Size limits of the store's JSON files (bytes): generous for real stores (a manifest of 10,000
# inputs is ~3 MB, a checksums.json of 100,000 files ~15 MB), far below memory trouble.
KIB, MIB = 1024, 1024 * 1024
POINTER_LIMIT = 1 * MIB  # store.json (the checkout log grows by ~150 bytes per checkout)
MANIFEST_LIMIT = 32 * MIB
ZARR_JSON_LIMIT = 32 * MIB  # the root zarr.json holds the consolidated metadata of every node
RECORD_LIMIT = 128 * MIB  # checksums.json, references.json
LOCK_LIMIT = 64 * KIB  # .lock
BUILD_JSON_LIMIT = 16 * MIB  # .build/*.json of a version being built
TABLE_LIMIT = 512 * MIB  # a Parquet table is read whole


class UnsafeFile(OSError):
    """A store file that is not a regular file, or larger than the reader's limit."""


class FolderNotFile(UnsafeFile, IsADirectoryError):
    """A folder where a file was expected (callers that catch IsADirectoryError still do)."""


def kind_of(mode: int) -> str:
    if stat.S_ISLNK(mode):
        return "a symbolic link"
    if stat.S_ISDIR(mode):
        return "a folder"
    if stat.S_ISFIFO(mode):
        return "a FIFO (named pipe)"
    if stat.S_ISCHR(mode) or stat.S_ISBLK(mode):
        return "a device"
    if stat.S_ISSOCK(mode):
        return "a socket"
    return "not a regular file"


def not_regular(path: str | Path, mode: int) -> UnsafeFile:
    """The error for a store entry that is a link, FIFO, device, ... (``mode`` from lstat)."""
    if stat.S_ISDIR(mode):
        return FolderNotFile(errno.EISDIR, "is a folder, not a file", str(path))
    return UnsafeFile(
        errno.EINVAL,
        f"is {kind_of(mode)}, not a regular file (a store holds regular "
        "files only; nothing is read through it)",
        str(path),
    )


def open_regular(path: str | Path) -> int:
    """A read-only descriptor of ``path``, which must be a regular file (see module doc).
    FileNotFoundError when absent; :class:`UnsafeFile` for a link, FIFO, device or folder."""
    flags = os.O_RDONLY | getattr(os, "O_NOFOLLOW", 0) | getattr(os, "O_NONBLOCK", 0)
    try:
        fd = os.open(path, flags)
    except OSError as exc:
        if exc.errno in (errno.ELOOP, errno.EMLINK, errno.ENXIO):
            try:
                mode = os.lstat(path).st_mode
            except OSError:
                raise exc from None
            raise not_regular(path, mode) from None
        raise
    try:
        mode = os.fstat(fd).st_mode
        if not stat.S_ISREG(mode):
            raise not_regular(path, mode)
        if hasattr(os, "O_NONBLOCK"):
            os.set_blocking(fd, True)
    except BaseException:
        os.close(fd)
        raise
    return fd


def too_large(path: str | Path, size: int, limit: int) -> UnsafeFile:
    return UnsafeFile(
        errno.EFBIG,
        f"{size:,} bytes, over the reader's limit of {limit:,} bytes for this file (not read)",
        str(path),
    )


def read_regular(path: str | Path, limit: int | None = None) -> bytes:
    """The bytes of the regular file ``path``; with ``limit``, :class:`UnsafeFile` when its size
    is over it (decided from fstat, and never more than ``limit + 1`` bytes read)."""
    fd = open_regular(path)
    with os.fdopen(fd, "rb") as handle:
        size = os.fstat(handle.fileno()).st_size
        if limit is not None and size > limit:
            raise too_large(path, size, limit)
        data = handle.read() if limit is None else handle.read(limit + 1)
    if limit is not None and len(data) > limit:
        raise too_large(path, len(data), limit)
    return data


def json_depth_problem(value: Any, max_depth: int = JSON_MAX_DEPTH) -> str | None:
    """ "nested deeper than N levels" when ``value`` is (walked without recursion, one iterator
    per open level, so a flat list of millions costs no copy), else None."""
    if not isinstance(value, dict | list):
        return None
    stack = [iter(value.values() if isinstance(value, dict) else value)]
    while stack:
        for child in stack[-1]:
            if isinstance(child, dict | list):
                if len(stack) >= max_depth:
                    return f"nested deeper than {max_depth} levels"
                stack.append(iter(child.values() if isinstance(child, dict) else child))
                break
        else:
            stack.pop()
    return None


def json_values_problem(data: bytes | str, max_values: int = JSON_MAX_VALUES) -> str | None:
    """A problem ("holds up to N values") when the text of ``data`` may hold more than
    ``max_values`` JSON values (an upper bound from its commas and opening brackets, which a
    string may also hold), else None. Counted without parsing."""
    if isinstance(data, str):
        count = data.count(",") + data.count("[") + data.count("{")
    else:
        count = data.count(b",") + data.count(b"[") + data.count(b"{")
    if count > max_values:
        return f"holds up to {count:,} values, over the reader's limit of {max_values:,}"
    return None


def parse_json(data: bytes | str, where: Any, what: str, *, max_depth: int = JSON_MAX_DEPTH) -> Any:
    """``data`` parsed as JSON; StoreError naming ``where`` ("unreadable <what>: ...") when it
    is not JSON, nested too deeply, holds too many values (:data:`JSON_MAX_VALUES`, checked
    before parsing) or a number too long to convert."""
    problem = json_values_problem(data)
    if problem is not None:
        raise StoreError(f"unreadable {what}: {problem} (not parsed)", where)
    try:
        value = json.loads(data)
    except RecursionError:
        raise StoreError(
            f"unreadable {what}: nested deeper than {max_depth} levels", where
        ) from None
    except ValueError as exc:  # JSONDecodeError, UnicodeDecodeError, int digits limit
        raise StoreError(f"unreadable {what}: {str(exc)[:200]}", where) from None
    problem = json_depth_problem(value, max_depth)
    if problem is not None:
        raise StoreError(f"unreadable {what}: {problem}", where)
    return value


def read_json(backend: Any, key: str, *, limit: int, what: str | None = None) -> Any:
    """The JSON file ``key`` of a store backend, read with ``limit`` bytes and
    :data:`JSON_MAX_DEPTH` levels at most. FileNotFoundError when it is absent; StoreError naming
    the file for anything else (not a regular file, too large, unreadable, not JSON)."""
    where = backend.where(key)
    label = what or key.rsplit("/", 1)[-1]
    try:
        data = backend.read_small(key, limit)
    except (FileNotFoundError, NotADirectoryError):
        raise FileNotFoundError(errno.ENOENT, "not found", str(where)) from None
    except OSError as exc:
        raise StoreError(f"unreadable {label}: {exc.strerror or exc}", where) from None
    return parse_json(data, where, label)


def special_entries(
    top: str | Path, *, skip_top: frozenset[str] = frozenset()
) -> list[tuple[str, str]]:
    """(relative POSIX path, what it is) of every entry below the local folder ``top`` that is
    not a regular file or a real folder: symbolic links (never followed), FIFOs, devices,
    sockets. ``top`` itself must be a real folder (checked by the caller)."""
    found: list[tuple[str, str]] = []
    pending = [(Path(top), "")]
    while pending:
        folder, rel = pending.pop()
        try:
            entries = list(os.scandir(folder))
        except OSError:
            continue
        for entry in entries:
            name = f"{rel}{entry.name}"
            if not rel and entry.name in skip_top:
                continue
            if entry.is_dir(follow_symlinks=False):
                pending.append((Path(entry.path), name + "/"))
            elif not entry.is_file(follow_symlinks=False):
                try:
                    mode = entry.stat(follow_symlinks=False).st_mode
                except OSError:
                    continue
                found.append((name, kind_of(mode)))
    return sorted(found)


__all__ = [
    "JSON_MAX_DEPTH",
    "JSON_MAX_VALUES",
    "UnsafeFile",
    "json_depth_problem",
    "json_values_problem",
    "open_regular",
    "parse_json",
    "read_json",
    "read_regular",
    "special_entries",
]
