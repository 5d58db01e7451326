"""Checksums of every data file of a version, recorded at commit and re-checked on demand.

At commit, just before ``manifest.json``, the writer calls :func:`record_checksums`, which writes
``versions/vN/checksums.json``::

    {"algorithm": "sha256",
     "files": {"sequences.parquet": {"bytes": 1234, "sha256": "..."},
               "data.zarr/motion/rotmat/c/0/0/0/0": {...}, ...},
     "digest": "<sha256 of the canonical JSON of files>"}

Every file of the version is listed except ``manifest.json`` and ``checksums.json`` itself.
Files carried over from the parent by hard link are the parent's very bytes, so their recorded
hash is copied from the parent's record instead of being recomputed.

:func:`verify_store` checks each version against its record: cheaply (every recorded file is
present with its recorded size, no unrecorded file has appeared, the record itself is intact) or
``deep`` (every file re-hashed). Each problem names the version, the zarr array and chunk or the
table, and the other versions that share the same file through a hard link, since corrupting one
inode corrupts every version that links to it.
"""

from __future__ import annotations

import hashlib
import json
import os
from collections.abc import Callable, Iterable
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from dancedata.store.build import BUILD_DIR
from dancedata.store.checksums import canonical_json, sha256_file
from dancedata.store.layout import (
    MANIFEST_FILE,
    TEMP_PREFIX,
    ZARR_DIR,
    StoreLayout,
    write_json_atomic,
)

CHECKSUMS_FILE = "checksums.json"
ALGORITHM = "sha256"
_NOT_HASHED = frozenset({MANIFEST_FILE, CHECKSUMS_FILE})
_HASH_THREADS = max(1, min(4, os.cpu_count() or 1))

FileKey = tuple[int, int]  # (st_dev, st_ino): one file on disk, whatever its names


# -- recording ---------------------------------------------------------------------------------
def data_files(version_dir: Path) -> list[str]:
    """Relative POSIX paths of the files a version's checksums cover, sorted."""
    found: list[str] = []
    for dirpath, dirnames, filenames in os.walk(version_dir):
        rel_dir = Path(dirpath).relative_to(version_dir)
        if rel_dir == Path("."):
            dirnames[:] = [d for d in dirnames if d != BUILD_DIR]  # resume state, not data
        dirnames.sort()
        for name in filenames:
            if name.startswith(TEMP_PREFIX):
                continue  # an atomic write in flight, never part of a committed version
            rel = (rel_dir / name).as_posix()
            if rel not in _NOT_HASHED:
                found.append(rel)
    return sorted(found)


def _file_key(path: Path) -> FileKey | None:
    try:
        st = path.stat()
    except OSError:
        return None
    return (st.st_dev, st.st_ino)


def _record_digest(files: dict[str, Any]) -> str:
    return hashlib.sha256(canonical_json(files).encode()).hexdigest()


def _hash_many(paths: list[Path]) -> list[str]:
    if len(paths) < 2 or _HASH_THREADS == 1:
        return [sha256_file(p) for p in paths]
    with ThreadPoolExecutor(_HASH_THREADS) as pool:  # hashlib releases the GIL on big blocks
        return list(pool.map(sha256_file, paths))


def record_checksums(version_dir: str | Path, parent_dir: str | Path | None = None) -> dict:
    """Hash every data file of the version being committed and write ``checksums.json``.

    A file that is the same inode as the parent's file at the same path (carried over by hard
    link) takes the parent's recorded hash; every other file is hashed.
    """
    version_dir = Path(version_dir)
    parent_files: dict[str, Any] = {}
    if parent_dir is not None:
        parent_record = load_record(Path(parent_dir))
        if parent_record is not None:
            parent_files = parent_record.get("files", {})
    files: dict[str, dict[str, Any]] = {}
    to_hash: list[str] = []
    for rel in data_files(version_dir):
        path = version_dir / rel
        size = path.stat().st_size
        inherited = parent_files.get(rel)
        if (
            inherited is not None
            and inherited.get("bytes") == size
            and _file_key(path) == _file_key(Path(parent_dir) / rel)  # type: ignore[arg-type]
        ):
            files[rel] = {"bytes": size, "sha256": inherited["sha256"]}
        else:
            files[rel] = {"bytes": size, "sha256": None}
            to_hash.append(rel)
    for rel, digest in zip(to_hash, _hash_many([version_dir / r for r in to_hash]), strict=True):
        files[rel]["sha256"] = digest
    record = {"algorithm": ALGORITHM, "files": files, "digest": _record_digest(files)}
    write_json_atomic(version_dir / CHECKSUMS_FILE, record)
    return record


def load_record(version_dir: Path) -> dict[str, Any] | None:
    """The parsed ``checksums.json`` of a version, or None when it has none or it is unreadable
    (:func:`check_record` says which)."""
    try:
        record = json.loads((version_dir / CHECKSUMS_FILE).read_text(encoding="utf-8"))
    except (OSError, UnicodeDecodeError, json.JSONDecodeError):
        return None
    return record if isinstance(record, dict) else None


# -- naming what a file is ---------------------------------------------------------------------
def describe_file(rel: str) -> str:
    """What a version-relative path holds, for messages: a chunk of a named zarr array, zarr
    metadata, a table, or a plain file."""
    parts = rel.split("/")
    if parts[0] == ZARR_DIR and len(parts) > 1:
        inner = parts[1:]
        if inner[-1] == "zarr.json":
            node = "/".join(inner[:-1]) or "/"
            return f"zarr metadata of {node}"
        index = len(inner)
        while index > 0 and inner[index - 1].isdigit():
            index -= 1
        if 0 < index < len(inner) and inner[index - 1] == "c":
            array = "/".join(inner[: index - 1])
            coords = ", ".join(inner[index:])
            return f"array {array} chunk ({coords})"
        return f"zarr file {'/'.join(inner)}"
    if len(parts) == 1 and rel.endswith(".parquet"):
        return f"table {rel[: -len('.parquet')]}"
    return f"file {rel}"


# -- verifying ---------------------------------------------------------------------------------
@dataclass
class HashCache:
    """sha256 per on-disk file, so a file shared by several versions is read once."""

    by_key: dict[tuple[int, int, int, int], str]

    @classmethod
    def empty(cls) -> HashCache:
        return cls(by_key={})

    def hashes(self, paths: list[Path]) -> list[str | None]:
        """sha256 of each path (None for a file that vanished), hashing each inode once."""
        keys = [_content_key(p) for p in paths]
        pending: dict[tuple[int, int, int, int], Path] = {}
        for key, path in zip(keys, paths, strict=True):
            if key is not None and key not in self.by_key:
                pending.setdefault(key, path)
        for key, digest in zip(pending, _hash_many(list(pending.values())), strict=True):
            self.by_key[key] = digest
        return [self.by_key.get(k) if k else None for k in keys]


def _content_key(path: Path) -> tuple[int, int, int, int] | None:
    try:
        st = path.stat()
    except OSError:
        return None
    return (st.st_dev, st.st_ino, st.st_size, st.st_mtime_ns)


def check_record(
    version_dir: Path,
    *,
    deep: bool,
    cache: HashCache | None = None,
    sharing: Callable[[Path], str] | None = None,
) -> list[str]:
    """Problems of one committed version against its ``checksums.json``.

    Without ``deep`` only presence, sizes and unrecorded files are checked; with ``deep`` every
    file is re-hashed. A version committed before checksums existed passes the cheap check and
    fails the deep one (there is nothing to verify against).
    """
    path = version_dir / CHECKSUMS_FILE
    if not path.exists():
        return [f"{CHECKSUMS_FILE}: missing, so the data cannot be verified"] if deep else []
    record = load_record(version_dir)
    if record is None:
        return [f"{CHECKSUMS_FILE}: unreadable (not JSON)"]
    files = record.get("files")
    if record.get("algorithm") != ALGORITHM or not isinstance(files, dict):
        return [f"{CHECKSUMS_FILE}: not a {ALGORITHM} file record"]
    if record.get("digest") != _record_digest(files):
        return [f"{CHECKSUMS_FILE}: its own digest does not match (the record is corrupted)"]
    shared = sharing or (lambda _p: "")
    problems: list[str] = []
    present = set(data_files(version_dir))
    for rel in sorted(present - set(files)):
        problems.append(f"{describe_file(rel)} ({rel}): file not recorded at commit")
    checked: list[str] = []
    for rel, entry in sorted(files.items()):
        target = version_dir / rel
        if rel not in present:
            problems.append(f"{describe_file(rel)} ({rel}): missing")
            continue
        size = target.stat().st_size
        if size != entry.get("bytes"):
            problems.append(
                f"{describe_file(rel)} ({rel}): {size} bytes, {entry.get('bytes')} recorded at "
                f"commit{shared(target)}"
            )
            continue
        checked.append(rel)
    if deep:
        digests = (cache or HashCache.empty()).hashes([version_dir / r for r in checked])
        for rel, digest in zip(checked, digests, strict=True):
            if digest != files[rel].get("sha256"):
                problems.append(
                    f"{describe_file(rel)} ({rel}): sha256 differs from the one recorded at "
                    f"commit (corrupted){shared(version_dir / rel)}"
                )
    return problems


def _sharing_index(layout: StoreLayout, versions: Iterable[str]) -> Callable[[Path], str]:
    """A function telling which other versions hold the same inode as a given file (the index
    is built on first use: only when there is something to report)."""
    owners: dict[FileKey, list[str]] = {}
    names = list(versions)

    def build() -> None:
        for name in names:
            vdir = layout.version_dir(name)
            for rel in data_files(vdir):
                key = _file_key(vdir / rel)
                if key is not None:
                    owners.setdefault(key, []).append(name)
        names.clear()

    def shared(path: Path) -> str:
        if names:
            build()
        key = _file_key(path)
        version = path.relative_to(layout.versions_dir).parts[0]
        others = [v for v in owners.get(key, []) if v != version] if key else []
        if not others:
            return ""
        return f"; the same file (hard link) is in {', '.join(others)}"

    return shared


def verify_store(store: str | Path, versions: list[str], *, deep: bool) -> dict[str, list[str]]:
    """Problems per version, for the given committed versions of ``store``."""
    layout = StoreLayout(store)
    cache = HashCache.empty()
    sharing = _sharing_index(layout, layout.committed_versions())
    return {
        name: check_record(layout.version_dir(name), deep=deep, cache=cache, sharing=sharing)
        for name in versions
    }
