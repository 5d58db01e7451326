"""The one storage interface a store is written against: bytes under keys, and how a finished
version becomes visible.

A *key* is a POSIX path relative to the store's root (``store.json``,
``versions/v3/data.zarr/motion/rotmat/zarr.json``); ``""`` is the root itself. Layout, version
writer, build area, integrity records and the reader use only the methods of
:class:`StoreBackend`; two implementations exist,
:class:`dancedata.store.backend_local.LocalBackend` (a directory) and
:class:`dancedata.store.backend_fsspec.FsspecBackend` (an fsspec URL: ``s3://bucket/prefix``,
...). :func:`dancedata.store.backend_open.make_backend` (above both implementations) turns
anything store-like (a path, a string, a URL or a backend) into one, as zarr-python's
``make_store_path`` does.

What differs between the two is said by capabilities, never by asking "is this remote?":

- ``renames_atomically``: a folder can be renamed in one step (a local filesystem). Then a
  version is committed by the rename of its folder, and a ``vN`` folder with a valid manifest
  is committed whatever store.json says. Without it (object stores) the single PUT of
  store.json is the commit point, and only versions up to the one it names are committed.
- ``identity(key)``: what says two keys hold the very same stored bytes (an inode locally, the
  object's ETag on S3), so that a file carried over from the parent takes its recorded hash.
"""

from __future__ import annotations

from abc import ABC, abstractmethod
from collections.abc import Hashable, Iterable, Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import Any

Bytes = bytes | bytearray | memoryview


TEMP_PREFIX = ".tmp-"  # a name being written or built; never part of a committed version


def json_bytes(value: Any) -> bytes:
    """How every JSON file of a store is written: sorted keys, 2-space indent, final newline."""
    import json

    return (json.dumps(value, indent=2, sort_keys=True) + "\n").encode("utf-8")


def join(*parts: str) -> str:
    """Keys joined with ``/``, empty parts left out (``join("", "a")`` is ``"a"``)."""
    return "/".join(p.strip("/") for p in parts if p and p.strip("/"))


def parent_key(key: str) -> str:
    return key.rsplit("/", 1)[0] if "/" in key else ""


def base_name(key: str) -> str:
    return key.rsplit("/", 1)[-1]


class StoreBackend(ABC):
    """Bytes under keys of one store root (see the module docstring)."""

    #: a folder is renamed in one atomic step (see the module docstring)
    renames_atomically: bool = False
    #: what the store root is called in messages
    root_noun: str = "prefix"

    # -- where things are (for messages and for callers that want paths) ----------------------
    @abstractmethod
    def where(self, key: str = "") -> Path | str:
        """What a key is called in messages: a Path locally, a URL on object storage."""

    @abstractmethod
    def describe(self) -> str:
        """The store root as the user wrote it (a path or a URL)."""

    def __str__(self) -> str:
        """:meth:`describe`: a message naming the store handed down as a backend reads as it
        did when the store was handed down as the path."""
        return self.describe()

    @abstractmethod
    def locator(self, key: str = "") -> str:
        """A string ``make_backend`` turns back into the storage at ``key`` from any process
        (an absolute path, a URL): what worker processes are given."""

    @abstractmethod
    def at(self, key: str) -> StoreBackend:
        """The same storage rooted at ``key`` (a version's folder, a build area)."""

    @abstractmethod
    def sibling(self, name: str) -> StoreBackend:
        """The same storage rooted at ``name`` next to this root (another version)."""

    @property
    def name(self) -> str:
        """The last component of the root (``v3`` for a version's folder)."""
        return base_name(str(self.where()).rstrip("/"))

    # -- reading -------------------------------------------------------------------------------
    @abstractmethod
    def read_bytes(self, key: str) -> bytes:
        """The object's bytes; FileNotFoundError when there is none."""

    def sha256(self, key: str) -> str:
        """Hex sha256 of the object's bytes."""
        import hashlib

        return hashlib.sha256(self.read_bytes(key)).hexdigest()

    def read_buffer(self, key: str) -> Any:
        """The object's bytes as a buffer numpy can view (a memory map where the platform has
        one, so big scratch files are not copied); FileNotFoundError when absent."""
        return self.read_bytes(key)

    @abstractmethod
    def is_file(self, key: str) -> bool: ...

    @abstractmethod
    def is_dir(self, key: str) -> bool:
        """True when something is stored under ``key/`` (a folder, or an object prefix)."""

    def exists(self, key: str) -> bool:
        return self.is_file(key) or self.is_dir(key)

    @abstractmethod
    def list_dir(self, key: str) -> list[str]:
        """Names of the direct children of ``key`` (files and folders), sorted; [] when
        there is nothing there."""

    @abstractmethod
    def find(self, key: str, *, skip_top: Iterable[str] = ()) -> list[str]:
        """Keys, relative to ``key``, of every file below it, sorted; top-level children named
        in ``skip_top`` are left out, symbolic links to folders are not followed."""

    @abstractmethod
    def size(self, key: str) -> int:
        """Bytes of a file (not following a symbolic link); FileNotFoundError when absent."""

    def file_sizes(self, key: str, *, skip_top: Iterable[str] = ()) -> dict[str, int]:
        """{key relative to ``key``: bytes} of every file below ``key`` (as :meth:`find`)."""
        return {rel: self.size(join(key, rel)) for rel in self.find(key, skip_top=skip_top)}

    @abstractmethod
    def identity(self, key: str) -> Hashable | None:
        """Equal for two keys that are one stored file (hard links to one inode); None when
        the file is absent or the backend stores every key separately (object stores)."""

    @abstractmethod
    def content_key(self, key: str) -> Hashable | None:
        """Changes whenever the bytes at ``key`` may have changed (inode, size and mtime; an
        ETag): a cache key for hashes and parsed files. None when absent, not a file (a
        folder) or unknown."""

    def shadowed(self) -> dict[str, str]:
        """{key: holding version} of files stored here although this version's references
        name another version as their holder (written after the commit); {} without
        references (see :mod:`dancedata.store.references`)."""
        return {}

    def links(self, key: str) -> list[str]:
        """Keys (relative to ``key``) of symbolic links below it; object stores have none."""
        return []

    def read_small(self, key: str, limit: int) -> bytes:
        """The bytes at ``key``, refused (OSError) without reading them when the object is over
        ``limit`` bytes (see :mod:`dancedata.store.untrusted`)."""
        from dancedata.store.untrusted import too_large

        size = self.size(key)
        if size > limit:
            raise too_large(self.where(key), size, limit)
        data = self.read_bytes(key)
        if len(data) > limit:
            raise too_large(self.where(key), len(data), limit)
        return data

    def special(self, key: str) -> str | None:
        """What the entry ``key`` is when it is neither a regular file nor a real folder ("a
        symbolic link", "a FIFO (named pipe)", "a device", ...); None otherwise or when absent.
        Object stores hold plain objects only."""
        return None

    def special_below(self, key: str, *, skip_top: Iterable[str] = ()) -> list[tuple[str, str]]:
        """(key relative to ``key``, what it is) of every entry below ``key`` that is neither a
        regular file nor a real folder (see :meth:`special`); object stores have none."""
        return []

    def is_regular(self, key: str) -> bool:
        """A plain file (not a symbolic link, not a folder)."""
        return self.is_file(key)

    # -- writing -------------------------------------------------------------------------------
    @abstractmethod
    def write_bytes(self, key: str, data: Bytes | Iterable[Bytes], *, durable: bool = True) -> None:
        """Store ``data`` (bytes, or pieces written back to back) at ``key`` atomically: a
        reader sees the old object or the new one, never part of one. ``durable``: flushed to
        the device before returning (a local fsync; object stores always are)."""

    @abstractmethod
    def create_exclusive(self, key: str, data: bytes) -> bool | None:
        """Create ``key`` only if it does not exist: True when created, False when it was
        there, None when the backend has no exclusive create."""

    def make_dir(self, key: str) -> None:
        """Create a folder (object stores have none: a prefix exists once an object does)."""
        return None

    def remove_empty_dir(self, key: str) -> None:
        """Remove a folder if it is empty (OSError when it is not); object stores have none."""
        return None

    @abstractmethod
    def delete(self, key: str) -> None:
        """Remove a file or everything under a folder/prefix; nothing there is fine."""

    @abstractmethod
    def carry_over(self, src: str, dst: str, *, skip_top: Iterable[str] = ()) -> None:
        """Recreate the committed folder ``src`` at ``dst`` so that ``dst`` can be changed
        without touching ``src``: hard links for data files locally (metadata copied), a
        server-side copy on object stores."""

    @abstractmethod
    def publish(
        self, tmp: str, final: str, *, leave_out: str, last: str, base: str | None = None
    ) -> None:
        """Make the finished folder ``tmp`` visible as ``final`` (which does not exist yet as
        a committed version): one rename locally, a copy on object stores with ``last``
        copied last, where files equal to those of the committed version ``base`` (the
        parent) are referenced instead of copied (:mod:`dancedata.store.references`).
        ``tmp/leave_out`` (build state) does not go along."""

    def version_view(self, key: str) -> StoreBackend:
        """The committed version folder ``key`` as readers see it: every file of the version at
        its own path, wherever it is stored (see :mod:`dancedata.store.references`)."""
        return self.at(key)

    @abstractmethod
    def writer_lock(self, *, wait: bool) -> Any:
        """The store's writer lock (``acquire()``, ``release()``), not yet taken."""

    # -- zarr ----------------------------------------------------------------------------------
    @abstractmethod
    def zarr_store(self, key: str, *, read_only: bool = False) -> Any:
        """A zarr v3 store object rooted at ``key``."""

    def invalidate(self) -> None:
        """Forget cached listings (object stores); local reads are never cached."""
        return None

    @contextmanager
    def storage_errors(self) -> Iterator[None]:
        """Run the block; backends may turn their failures into one clear line."""
        yield
