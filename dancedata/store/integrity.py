"""Checksums of every data file of a version, recorded at commit and re-checked on demand.

At commit, right after ``manifest.json``, the writer calls :func:`record_checksums`, which
writes ``versions/vN/checksums.json``::

    {"algorithm": "sha256", "record_version": 2,
     "files": {"sequences.parquet": {"bytes": 1234, "sha256": "..."},
               "data.zarr/motion/rotmat/c/0/0/0/0": {...}, ...},
     "manifest": {"bytes": 812, "sha256": "..."},
     "parent": {"version": "v2", "checksums_sha256": "..."},
     "digest": "<sha256 of the canonical JSON of every other key>"}

``files`` lists every file of the version except ``manifest.json`` and ``checksums.json``;
every chunk that the shape and chunk grid of an array call for must be among them (a version
is refused at commit when one is missing, or when a file is a symbolic link), so a deleted
chunk can never be carried into a child. Files carried over from the parent by hard link are the
parent's very bytes, so their recorded hash is copied from the parent's record instead of being
recomputed (after checking that the parent's file is a regular file of its recorded size).

The chain of records: ``manifest.json`` is covered by ``manifest`` in its version's record; the
record is covered by its own ``digest`` (corruption) and by its children's ``parent`` entry
(a record rewritten after a child was committed is caught); the newest record's digest is shown
by ``dancedata info`` for anyone who wants to pin it outside the store. Records written before
``record_version`` 2 lack ``manifest`` and ``parent`` and are checked as before.

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
import stat
from collections.abc import Callable, Iterable
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from dancedata.errors import StoreError
from dancedata.store.build import BUILD_DIR
from dancedata.store.checksums import canonical_json, sha256_file
from dancedata.store.chunks import ChunkGrid
from dancedata.store.layout import (
    MANIFEST_FILE,
    TEMP_PREFIX,
    ZARR_DIR,
    StoreLayout,
    write_json_atomic,
)

CHECKSUMS_FILE = "checksums.json"
ALGORITHM = "sha256"
RECORD_VERSION = 2
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


def _record_digest(record: dict[str, Any]) -> str:
    """The ``digest`` of a record: over ``files`` alone for records before version 2, over
    every key but ``digest`` since."""
    if not isinstance(record.get("record_version"), int) or record["record_version"] < 2:
        return hashlib.sha256(canonical_json(record.get("files")).encode()).hexdigest()
    body = {k: v for k, v in record.items() if k != "digest"}
    return hashlib.sha256(canonical_json(body).encode()).hexdigest()


def _hash_many(paths: list[Path]) -> list[str]:
    if len(paths) < 2 or _HASH_THREADS == 1:
        return [sha256_file(p) for p in paths]
    with ThreadPoolExecutor(_HASH_THREADS) as pool:  # hashlib releases the GIL on big blocks
        return list(pool.map(sha256_file, paths))


def array_grids(version_dir: Path) -> dict[str, ChunkGrid]:
    """Every regular-grid zarr v3 array of a version's data.zarr, by array path
    (``motion/rotmat``); arrays whose metadata cannot be read are left out (validate reports
    them when it opens them)."""
    root = version_dir / ZARR_DIR
    grids: dict[str, ChunkGrid] = {}
    if not root.is_dir():
        return grids
    for dirpath, dirnames, filenames in os.walk(root):
        dirnames[:] = [d for d in dirnames if d != "c"]  # chunk folders hold no metadata
        if "zarr.json" not in filenames:
            continue
        try:
            meta = json.loads((Path(dirpath) / "zarr.json").read_text(encoding="utf-8"))
        except (OSError, ValueError):
            continue
        grid = ChunkGrid.from_metadata(meta)
        if grid is not None:
            grids[Path(dirpath).relative_to(root).as_posix()] = grid
    return grids


def required_chunk_files(version_dir: Path) -> dict[str, tuple[str, ChunkGrid]]:
    """Version-relative path of every chunk file the arrays' shapes and chunk grids call for,
    mapped to (array path, grid)."""
    required: dict[str, tuple[str, ChunkGrid]] = {}
    for array, grid in array_grids(version_dir).items():
        base = f"{ZARR_DIR}/{array}/" if array != "." else f"{ZARR_DIR}/"
        for key in grid.chunk_keys():
            required[base + key] = (array, grid)
    return required


def symlinks(version_dir: Path) -> list[str]:
    """Version-relative paths of symbolic links (files or folders) inside a version: a store
    holds regular files only, and a link could point anywhere."""
    found = []
    for dirpath, dirnames, filenames in os.walk(version_dir):
        rel_dir = Path(dirpath).relative_to(version_dir)
        for name in [*dirnames, *filenames]:
            if os.path.islink(os.path.join(dirpath, name)):
                found.append((rel_dir / name).as_posix())
    return sorted(found)


def _is_regular(path: Path) -> bool:
    try:
        return stat.S_ISREG(os.lstat(path).st_mode)
    except OSError:
        return False


def _parent_entry(parent_dir: Path | None) -> dict[str, Any] | None:
    if parent_dir is None or not (parent_dir / CHECKSUMS_FILE).is_file():
        return None
    digest = sha256_file(parent_dir / CHECKSUMS_FILE)
    return {"version": parent_dir.name, "checksums_sha256": digest}


def commit_problems(version_dir: Path, parent_dir: Path | None) -> list[str]:
    """Why a version being committed must not be: a symbolic link anywhere in it, or a chunk
    its arrays call for that is absent (a crc32c array writes every chunk; an older array's
    chunk is required when the parent's record lists it)."""
    problems = [
        f"{rel}: is a symbolic link (a store holds regular files only)"
        for rel in symlinks(version_dir)
    ]
    if parent_dir is not None:
        problems += [
            f"{rel}: is a symbolic link in {parent_dir.name} (a store holds regular files only)"
            for rel in symlinks(parent_dir)
        ]
    parent_files: dict[str, Any] = {}
    if parent_dir is not None:
        parent_files = (load_record(parent_dir) or {}).get("files") or {}
    present = set(data_files(version_dir))
    origin = f" (carried over from {parent_dir.name})" if parent_dir is not None else ""
    for rel, (_array, grid) in sorted(required_chunk_files(version_dir).items()):
        if rel in present:
            continue
        if grid.crc32c or rel in parent_files:
            problems.append(f"{describe_file(rel)} ({rel}): missing{origin}")
    return problems


def record_checksums(version_dir: str | Path, parent_dir: str | Path | None = None) -> dict:
    """Hash every data file of the version being committed and write ``checksums.json``.

    Refuses (StoreError naming the parent, the array and the chunk) a version with a symbolic
    link or a missing required chunk (:func:`commit_problems`), or carrying over a file that no
    longer matches the parent's record. A file that is the same inode as the parent's file at
    the same path (carried over by hard link) takes the parent's recorded hash; every other
    file is hashed. ``manifest.json``, when already written, is recorded under ``manifest``.
    """
    version_dir = Path(version_dir)
    parent = Path(parent_dir) if parent_dir is not None else None
    where = parent if parent is not None else version_dir
    problems = commit_problems(version_dir, parent)
    parent_files: dict[str, Any] = {}
    if parent is not None:
        parent_record = load_record(parent)
        if parent_record is not None and isinstance(parent_record.get("files"), dict):
            parent_files = parent_record["files"]
    files: dict[str, dict[str, Any]] = {}
    to_hash: list[str] = []
    for rel in data_files(version_dir):
        path = version_dir / rel
        size = path.lstat().st_size
        inherited = parent_files.get(rel)
        same_file = (
            parent is not None
            and _is_regular(parent / rel)
            and _file_key(path) == _file_key(parent / rel)
        )
        if same_file and inherited is not None:
            if inherited.get("bytes") != size:
                problems.append(
                    f"{describe_file(rel)} ({rel}): {size} bytes in {parent.name}, "  # type: ignore[union-attr]
                    f"{inherited.get('bytes')} recorded at its commit (damaged since)"
                )
                continue
            files[rel] = {"bytes": size, "sha256": inherited["sha256"]}
        else:
            files[rel] = {"bytes": size, "sha256": None}
            to_hash.append(rel)
    if problems:
        more = f" (and {len(problems) - 3} more)" if len(problems) > 3 else ""
        raise StoreError(
            "cannot commit a version built on damaged data: "
            + "; ".join(problems[:3])
            + more
            + "; run `dancedata validate --deep` on the store",
            where,
        )
    for rel, digest in zip(to_hash, _hash_many([version_dir / r for r in to_hash]), strict=True):
        files[rel]["sha256"] = digest
    record: dict[str, Any] = {
        "algorithm": ALGORITHM,
        "record_version": RECORD_VERSION,
        "files": files,
        "parent": _parent_entry(parent),
    }
    manifest = version_dir / MANIFEST_FILE
    if manifest.is_file():
        record["manifest"] = {"bytes": manifest.stat().st_size, "sha256": sha256_file(manifest)}
    record["digest"] = _record_digest(record)
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


def _manifest_problems(version_dir: Path, record: dict[str, Any]) -> list[str]:
    """manifest.json against the ``manifest`` entry of a version-2 record (always re-hashed:
    it is small, and an edited fingerprint or stage list must not pass even a cheap check)."""
    entry = record.get("manifest")
    if not isinstance(entry, dict):
        return []
    path = version_dir / MANIFEST_FILE
    try:
        size = path.stat().st_size
        digest = sha256_file(path)
    except OSError:
        return [f"{MANIFEST_FILE}: missing or unreadable"]
    if size != entry.get("bytes") or digest != entry.get("sha256"):
        return [
            f"{MANIFEST_FILE}: differs from the one recorded at commit in {CHECKSUMS_FILE} "
            "(edited after commit: its fingerprint, stages or inputs cannot be trusted)"
        ]
    return []


def _parent_problems(version_dir: Path, record: dict[str, Any]) -> list[str]:
    """The parent's checksums.json against the hash this version recorded of it."""
    entry = record.get("parent")
    if not isinstance(entry, dict) or not isinstance(entry.get("version"), str):
        return []
    name = entry["version"]
    path = version_dir.parent / name / CHECKSUMS_FILE
    try:
        digest = sha256_file(path)
    except OSError:
        return [f"{CHECKSUMS_FILE}: parent {name}'s record is gone (recorded at commit)"]
    if digest != entry.get("checksums_sha256"):
        return [
            f"{CHECKSUMS_FILE}: parent {name}'s {CHECKSUMS_FILE} differs from the one recorded "
            "when this version was committed (the parent's record was rewritten)"
        ]
    return []


def _unrecorded_chunks(version_dir: Path, files: dict[str, Any]) -> list[str]:
    """Chunks of crc32c arrays (every chunk written) that the record does not list: a record
    built from the files present after a chunk went missing."""
    problems = []
    for rel, (_array, grid) in sorted(required_chunk_files(version_dir).items()):
        if grid.crc32c and rel not in files:
            problems.append(
                f"{describe_file(rel)} ({rel}): required by the array's shape and chunk grid "
                "but not recorded at commit"
            )
    return problems


def check_record(
    version_dir: Path,
    *,
    deep: bool,
    cache: HashCache | None = None,
    sharing: Callable[[Path], str] | None = None,
) -> list[str]:
    """Problems of one committed version against its ``checksums.json``.

    Without ``deep`` only presence, sizes, unrecorded files, symbolic links, required chunks,
    the manifest and the parent's record are checked; with ``deep`` every file is re-hashed. A
    version committed before checksums existed passes the cheap check and fails the deep one
    (there is nothing to verify against).
    """
    links = [
        f"{describe_file(rel)} ({rel}): is a symbolic link (a store holds regular files only)"
        for rel in symlinks(version_dir)
    ]
    path = version_dir / CHECKSUMS_FILE
    if not path.exists():
        missing = [f"{CHECKSUMS_FILE}: missing, so the data cannot be verified"] if deep else []
        return links + missing
    record = load_record(version_dir)
    if record is None:
        return [*links, f"{CHECKSUMS_FILE}: unreadable (not JSON)"]
    files = record.get("files")
    if (
        record.get("algorithm") != ALGORITHM
        or not isinstance(files, dict)
        or not all(isinstance(e, dict) for e in files.values())
    ):
        return [*links, f"{CHECKSUMS_FILE}: not a {ALGORITHM} file record"]
    if record.get("digest") != _record_digest(record):
        return [
            *links,
            f"{CHECKSUMS_FILE}: its own digest does not match (the record is corrupted)",
        ]
    shared = sharing or (lambda _p: "")
    problems: list[str] = [*links]
    problems += _manifest_problems(version_dir, record)
    problems += _parent_problems(version_dir, record)
    problems += _unrecorded_chunks(version_dir, files)
    present = set(data_files(version_dir))
    for rel in sorted(present - set(files)):
        problems.append(f"{describe_file(rel)} ({rel}): file not recorded at commit")
    checked: list[str] = []
    for rel, entry in sorted(files.items()):
        target = version_dir / rel
        if rel not in present:
            problems.append(f"{describe_file(rel)} ({rel}): missing")
            continue
        if not _is_regular(target):
            continue  # a symbolic link: reported above, never followed
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
