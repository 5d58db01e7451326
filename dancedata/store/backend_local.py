"""A store in a local directory: files written through a temporary name, fsync and rename;
versions committed by renaming their folder; parents' data files shared by hard links."""

from __future__ import annotations

import contextlib
import os
import secrets
import shutil
import stat
from collections.abc import Hashable, Iterable
from pathlib import Path
from typing import Any

from dancedata.store.backend import TEMP_PREFIX, Bytes, StoreBackend, join
from dancedata.store.untrusted import kind_of, open_regular, read_regular, special_entries

# Files that are rewritten when a version changes (zarr metadata): copied into a child, never
# hard-linked, so that updating them never touches the parent.
COPIED_NAMES = frozenset({"zarr.json", ".zattrs", ".zgroup", ".zarray", "manifest.json"})


def fsync_dir(path: Path) -> None:
    """Flush a directory entry (a rename) to disk where the platform allows it."""
    try:
        fd = os.open(path, os.O_RDONLY)
    except OSError:
        return
    try:
        os.fsync(fd)
    except OSError:
        pass
    finally:
        os.close(fd)


def write_file_atomic(path: Path, data: Bytes | Iterable[Bytes], *, durable: bool = True) -> None:
    """Write ``path`` through a temporary file and a rename (fsync'd when ``durable``), so
    readers see either the old file or the new one; a failure leaves no temporary behind."""
    tmp = path.with_name(f"{TEMP_PREFIX}{path.name}.{os.getpid()}")
    pieces = [data] if isinstance(data, bytes | bytearray | memoryview) else data
    try:
        with open(tmp, "wb") as handle:
            for piece in pieces:
                handle.write(piece)
            if durable:
                handle.flush()
                os.fsync(handle.fileno())
        os.replace(tmp, path)
    except BaseException:
        # a full disk or a kill mid-write: leave no half-written temporary behind
        with contextlib.suppress(OSError):
            tmp.unlink()
        raise
    if durable:
        fsync_dir(path.parent)


class LocalBackend(StoreBackend):
    """A store rooted at a local directory."""

    renames_atomically = True
    root_noun = "directory"

    def __init__(self, root: Path) -> None:
        self.root = Path(root)

    def __repr__(self) -> str:
        return f"LocalBackend({str(self.root)!r})"

    def __eq__(self, other: object) -> bool:
        return isinstance(other, LocalBackend) and other.root == self.root

    def __hash__(self) -> int:
        return hash(self.root)

    def path(self, key: str) -> Path:
        return self.root / key if key else self.root

    def where(self, key: str = "") -> Path:
        return self.path(key)

    def describe(self) -> str:
        return str(self.root)

    def locator(self, key: str = "") -> str:
        return str(self.path(key).resolve())

    def at(self, key: str) -> LocalBackend:
        return LocalBackend(self.path(key))

    def sibling(self, name: str) -> LocalBackend:
        return LocalBackend(self.root.parent / name)

    # -- reading -------------------------------------------------------------------------------
    def read_bytes(self, key: str) -> bytes:
        # regular files only: never through a symbolic link, never from a FIFO or a device
        return read_regular(self.path(key))

    def read_small(self, key: str, limit: int) -> bytes:
        return read_regular(self.path(key), limit)

    def sha256(self, key: str) -> str:
        from dancedata.store.checksums import sha256_handle  # read in blocks, never whole

        with os.fdopen(open_regular(self.path(key)), "rb") as handle:
            return sha256_handle(handle)

    def read_buffer(self, key: str) -> Any:
        import numpy as np

        with os.fdopen(open_regular(self.path(key)), "rb") as handle:
            if os.fstat(handle.fileno()).st_size == 0:
                return np.zeros(0, dtype=np.uint8)
            return np.memmap(handle, dtype=np.uint8, mode="r")

    def special(self, key: str) -> str | None:
        try:
            mode = os.lstat(self.path(key)).st_mode
        except OSError:
            return None
        if stat.S_ISREG(mode) or stat.S_ISDIR(mode):
            return None
        return kind_of(mode)

    def special_below(self, key: str, *, skip_top: Iterable[str] = ()) -> list[tuple[str, str]]:
        return special_entries(self.path(key), skip_top=frozenset(skip_top))

    def is_file(self, key: str) -> bool:
        return self.path(key).is_file()

    def is_dir(self, key: str) -> bool:
        return self.path(key).is_dir()

    def exists(self, key: str) -> bool:
        return self.path(key).exists()

    def list_dir(self, key: str) -> list[str]:
        folder = self.path(key)
        if not folder.is_dir():
            return []
        return sorted(entry.name for entry in folder.iterdir())

    def find(self, key: str, *, skip_top: Iterable[str] = ()) -> list[str]:
        # plain strings, not a Path per file: validate lists every chunk of every version
        top = os.fspath(self.path(key))
        skip = set(skip_top)
        found: list[str] = []
        for dirpath, dirnames, filenames in os.walk(top):
            prefix = _posix_prefix(dirpath, top)
            if not prefix:
                dirnames[:] = [d for d in dirnames if d not in skip]
                filenames = [f for f in filenames if f not in skip]
            found.extend(prefix + name for name in filenames)
        return sorted(found)

    def size(self, key: str) -> int:
        return self.path(key).lstat().st_size

    def identity(self, key: str) -> Hashable | None:
        try:
            st = self.path(key).stat()
        except OSError:
            return None
        return (st.st_dev, st.st_ino)

    def content_key(self, key: str) -> Hashable | None:
        try:
            st = self.path(key).stat()
        except OSError:
            return None
        if not stat.S_ISREG(st.st_mode):  # a folder, FIFO or device has no content to key
            return None
        return (st.st_dev, st.st_ino, st.st_size, st.st_mtime_ns)

    def links(self, key: str) -> list[str]:
        top = os.fspath(self.path(key))
        found = []
        for dirpath, dirnames, filenames in os.walk(top):
            prefix = _posix_prefix(dirpath, top)
            for name in [*dirnames, *filenames]:
                if os.path.islink(os.path.join(dirpath, name)):
                    found.append(prefix + name)
        return sorted(found)

    def is_regular(self, key: str) -> bool:
        try:
            return stat.S_ISREG(os.lstat(self.path(key)).st_mode)
        except OSError:
            return False

    # -- writing -------------------------------------------------------------------------------
    def write_bytes(self, key: str, data: Bytes | Iterable[Bytes], *, durable: bool = True) -> None:
        path = self.path(key)
        path.parent.mkdir(parents=True, exist_ok=True)
        write_file_atomic(path, data, durable=durable)

    def create_exclusive(self, key: str, data: bytes) -> bool | None:
        path = self.path(key)
        try:
            fd = os.open(path, os.O_WRONLY | os.O_CREAT | os.O_EXCL, 0o644)
        except FileExistsError:
            return False
        with os.fdopen(fd, "wb") as handle:
            handle.write(data)
        return True

    def make_dir(self, key: str) -> None:
        self.path(key).mkdir(parents=True, exist_ok=True)

    def remove_empty_dir(self, key: str) -> None:
        if self.path(key).is_dir():
            self.path(key).rmdir()

    def delete(self, key: str) -> None:
        path = self.path(key)
        if path.is_dir() and not path.is_symlink():
            shutil.rmtree(path, ignore_errors=True)
        elif path.exists() or path.is_symlink():
            path.unlink()

    def carry_over(self, src: str, dst: str, *, skip_top: Iterable[str] = ()) -> None:
        """Metadata copied, data files hard-linked (copied when the filesystem refuses
        links): committed versions are immutable and zarr replaces files by rename."""
        source_root, target_root = self.path(src), self.path(dst)
        skip = set(skip_top)
        for dirpath, dirnames, filenames in os.walk(source_root):
            rel = Path(dirpath).relative_to(source_root)
            if rel == Path("."):
                dirnames[:] = [d for d in dirnames if d not in skip]
                filenames = [f for f in filenames if f not in skip]
            (target_root / rel).mkdir(parents=True, exist_ok=True)
            for name in filenames:
                source, target = Path(dirpath) / name, target_root / rel / name
                if name in COPIED_NAMES:
                    shutil.copy2(source, target)
                    continue
                try:
                    os.link(source, target)
                except OSError:
                    shutil.copy2(source, target)

    def publish(
        self, tmp: str, final: str, *, leave_out: str, last: str, base: str | None = None
    ) -> None:
        """One rename of the folder (atomic). The build state leaves first by a rename of its
        own, so a kill anywhere before the commit rename still finds it to resume from. (The
        parent's files are shared by hard links already: ``base`` is not needed.)"""
        source = self.path(tmp)
        spent = None
        if (source / leave_out).exists():
            spent = source.parent / f"{TEMP_PREFIX}spent-{secrets.token_hex(6)}"
            os.rename(source / leave_out, spent)
        os.rename(source, self.path(final))
        fsync_dir(self.path(final).parent)
        if spent is not None:
            shutil.rmtree(spent, ignore_errors=True)

    def writer_lock(self, *, wait: bool) -> Any:
        from dancedata.store.lock import StoreLock

        return StoreLock(self.root, wait=wait)

    # -- zarr ----------------------------------------------------------------------------------
    def zarr_store(self, key: str, *, read_only: bool = False) -> Any:
        from zarr.storage import LocalStore

        return LocalStore(str(self.path(key)), read_only=read_only)


def unique_suffix() -> str:
    """``<pid>-<random>``: a temporary name no other process uses."""
    return f"{os.getpid()}-{secrets.token_hex(4)}"


def _posix_prefix(dirpath: str, top: str) -> str:
    """``dirpath`` (a folder os.walk gave under ``top``) relative to ``top`` as a POSIX prefix
    ending in ``/``; ``""`` for ``top`` itself."""
    rel = os.path.relpath(dirpath, top)
    return "" if rel == "." else rel.replace(os.sep, "/") + "/"


__all__ = ["LocalBackend", "fsync_dir", "join", "write_file_atomic"]
