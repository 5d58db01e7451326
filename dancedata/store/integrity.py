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
import os
from collections.abc import Callable, Hashable, Iterable
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from dancedata.errors import StoreError
from dancedata.store.backend import TEMP_PREFIX, StoreBackend, json_bytes
from dancedata.store.backend_open import make_backend
from dancedata.store.build import BUILD_DIR
from dancedata.store.checksums import canonical_json
from dancedata.store.chunks import ChunkGrid
from dancedata.store.layout import MANIFEST_FILE, ZARR_DIR, StoreLayout
from dancedata.store.untrusted import RECORD_LIMIT, ZARR_JSON_LIMIT, read_json

CHECKSUMS_FILE = "checksums.json"
ALGORITHM = "sha256"
RECORD_VERSION = 2
_NOT_HASHED = frozenset({MANIFEST_FILE, CHECKSUMS_FILE})
_HASH_THREADS = max(1, min(4, os.cpu_count() or 1))

# A version folder: a local path, a URL, or a backend rooted at it.
VersionLike = str | Path | StoreBackend


def _version(where: VersionLike) -> StoreBackend:
    return make_backend(where)


def sha256_key(backend: StoreBackend, key: str) -> str:
    """Hex sha256 of one stored file (see :meth:`StoreBackend.sha256`)."""
    return backend.sha256(key)


# -- recording ---------------------------------------------------------------------------------
def data_file_sizes(version_dir: VersionLike) -> dict[str, int]:
    """{relative POSIX path: bytes} of the files a version's checksums cover, sorted."""
    version = _version(version_dir)
    found = version.file_sizes("", skip_top=[BUILD_DIR])  # resume state, not data
    return {
        rel: size
        for rel, size in found.items()
        # an atomic write in flight is never part of a committed version
        if not rel.rsplit("/", 1)[-1].startswith(TEMP_PREFIX) and rel not in _NOT_HASHED
    }


def data_files(version_dir: VersionLike) -> list[str]:
    """Relative POSIX paths of the files a version's checksums cover, sorted."""
    version = _version(version_dir)
    return sorted(
        rel
        for rel in version.find("", skip_top=[BUILD_DIR])
        if not rel.rsplit("/", 1)[-1].startswith(TEMP_PREFIX) and rel not in _NOT_HASHED
    )


def _record_digest(record: dict[str, Any]) -> str:
    """The ``digest`` of a record: over ``files`` alone for records before version 2, over
    every key but ``digest`` since."""
    if not isinstance(record.get("record_version"), int) or record["record_version"] < 2:
        return hashlib.sha256(canonical_json(record.get("files")).encode()).hexdigest()
    body = {k: v for k, v in record.items() if k != "digest"}
    return hashlib.sha256(canonical_json(body).encode()).hexdigest()


def _hash_many(backend: StoreBackend, keys: list[str]) -> list[str]:
    if len(keys) < 2 or _HASH_THREADS == 1:
        return [sha256_key(backend, k) for k in keys]
    with ThreadPoolExecutor(_HASH_THREADS) as pool:  # hashlib releases the GIL on big blocks
        return list(pool.map(lambda k: sha256_key(backend, k), keys))


def array_grids(version_dir: VersionLike) -> dict[str, ChunkGrid]:
    """Every regular-grid zarr v3 array of a version's data.zarr, by array path
    (``motion/rotmat``); arrays whose metadata cannot be read or is out of bounds are left out
    (validate reports them from :func:`dancedata.store.reader.metadata_problems`)."""
    version = _version(version_dir)
    grids: dict[str, ChunkGrid] = {}
    if not version.is_dir(ZARR_DIR):
        return grids
    for rel in version.find(ZARR_DIR):
        parts = rel.split("/")
        if parts[-1] != "zarr.json" or "c" in parts[:-1]:
            continue  # chunk folders hold no metadata
        try:
            meta = read_json(version, f"{ZARR_DIR}/{rel}", limit=ZARR_JSON_LIMIT)
        except (OSError, StoreError):
            continue
        grid = ChunkGrid.from_metadata(meta)
        if grid is not None:
            grids["/".join(parts[:-1]) or "."] = grid
    return grids


# An array's chunks are listed one by one only when it declares at most this many more chunks
# than its folder holds files: a zarr.json declaring millions of chunks is one problem, found by
# arithmetic, never millions of keys in memory or lines of output.
MAX_MISSING_LISTED = 1_000


def _chunk_files_per_array(version: StoreBackend) -> dict[str, int]:
    """How many chunk files each array folder of data.zarr holds (by array path)."""
    found: dict[str, int] = {}
    prefix = f"{ZARR_DIR}/"
    for rel in data_files(version):
        if not rel.startswith(prefix):
            continue
        inner = rel[len(prefix) :]
        head: str | None  # the array path, None for a file that is no chunk
        head, sep, _tail = inner.partition("/c/")
        if not sep:
            head = inner[:-2] if inner.endswith("/c") else None
        if head is not None:
            found[head] = found.get(head, 0) + 1
    return found


def chunk_requirements(
    version_dir: VersionLike,
) -> tuple[dict[str, tuple[str, ChunkGrid]], list[str]]:
    """(every chunk file the arrays' shapes and chunk grids call for, by version-relative path,
    mapped to (array path, grid); one problem per array that declares more chunks than its
    folder holds and than can be listed, instead of its chunks)."""
    version = _version(version_dir)
    required: dict[str, tuple[str, ChunkGrid]] = {}
    problems: list[str] = []
    present: dict[str, int] | None = None
    for array, grid in array_grids(version).items():
        base = f"{ZARR_DIR}/{array}/" if array != "." else f"{ZARR_DIR}/"
        if grid.n_chunks > MAX_MISSING_LISTED:
            if present is None:
                present = _chunk_files_per_array(version)
            held = present.get(array, 0)
            if grid.n_chunks > held + MAX_MISSING_LISTED:
                if not grid.crc32c:
                    continue  # an older array may skip fill-value chunks: not required here
                problems.append(
                    f"zarr metadata of {array} ({base}zarr.json): its shape {list(grid.shape)} "
                    f"and chunk shape {list(grid.chunk_shape)} call for {grid.n_chunks:,} "
                    f"chunks, but its folder holds {held:,} (not listed one by one)"
                )
                continue
        for key in grid.chunk_keys():
            required[base + key] = (array, grid)
    return required, problems


def required_chunk_files(version_dir: VersionLike) -> dict[str, tuple[str, ChunkGrid]]:
    """Version-relative path of every chunk file the arrays' shapes and chunk grids call for,
    mapped to (array path, grid) (arrays declaring more than can be listed are left out:
    :func:`chunk_requirements` names them)."""
    return chunk_requirements(version_dir)[0]


def special_files(version: StoreBackend) -> list[str]:
    """One problem per entry of a version that is a symbolic link, a FIFO, a device or a
    socket: a store holds regular files only, and nothing is read through such an entry."""
    return [
        f"{describe_file(rel)} ({rel}): is {kind} (a store holds regular files only)"
        for rel, kind in version.special_below("", skip_top=[BUILD_DIR])
    ]


def symlinks(version_dir: VersionLike) -> list[str]:
    """Version-relative paths of symbolic links (files or folders) inside a version: a store
    holds regular files only, and a link could point anywhere."""
    return _version(version_dir).links("")


def _parent_entry(parent: StoreBackend | None) -> dict[str, Any] | None:
    if parent is None or not parent.is_file(CHECKSUMS_FILE):
        return None
    digest = sha256_key(parent, CHECKSUMS_FILE)
    return {"version": parent.name, "checksums_sha256": digest}


def commit_problems(version_dir: VersionLike, parent_dir: VersionLike | None) -> list[str]:
    """Why a version being committed must not be: a symbolic link anywhere in it, or a chunk
    its arrays call for that is absent (a crc32c array writes every chunk; an older array's
    chunk is required when the parent's record lists it)."""
    version = _version(version_dir)
    parent = _version(parent_dir) if parent_dir is not None else None
    problems = [
        f"{rel}: is a symbolic link (a store holds regular files only)" for rel in symlinks(version)
    ]
    if parent is not None:
        problems += [
            f"{rel}: is a symbolic link in {parent.name} (a store holds regular files only)"
            for rel in symlinks(parent)
        ]
    parent_files: dict[str, Any] = {}
    if parent is not None:
        parent_files = (load_record(parent) or {}).get("files") or {}
    present = set(data_files(version))
    origin = f" (carried over from {parent.name})" if parent is not None else ""
    required, too_many = chunk_requirements(version)
    problems += too_many
    for rel, (_array, grid) in sorted(required.items()):
        if rel in present:
            continue
        if grid.crc32c or rel in parent_files:
            problems.append(f"{describe_file(rel)} ({rel}): missing{origin}")
    return problems


def record_checksums(
    version_dir: VersionLike, parent_dir: VersionLike | None = None
) -> dict[str, Any]:
    """Hash every data file of the version being committed and write ``checksums.json``.

    Refuses (StoreError naming the parent, the array and the chunk) a version with a symbolic
    link or a missing required chunk (:func:`commit_problems`), or carrying over a file that no
    longer matches the parent's record. A file that is the same stored file as the parent's
    file at the same path (carried over by hard link) takes the parent's recorded hash; every
    other file is hashed. ``manifest.json``, when already written, is recorded under
    ``manifest``.
    """
    version = _version(version_dir)
    parent = _version(parent_dir) if parent_dir is not None else None
    where = parent.where() if parent is not None else version.where()
    problems = commit_problems(version, parent)
    parent_files: dict[str, Any] = {}
    if parent is not None:
        parent_record = load_record(parent)
        if parent_record is not None and isinstance(parent_record.get("files"), dict):
            parent_files = parent_record["files"]
    files: dict[str, dict[str, Any]] = {}
    to_hash: list[str] = []
    for rel, size in data_file_sizes(version).items():
        inherited = parent_files.get(rel)
        same_file = False
        if parent is not None and inherited is not None:
            mine = version.identity(rel)
            same_file = mine is not None and parent.is_regular(rel) and mine == parent.identity(rel)
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
    for rel, digest in zip(to_hash, _hash_many(version, to_hash), strict=True):
        files[rel]["sha256"] = digest
    record: dict[str, Any] = {
        "algorithm": ALGORITHM,
        "record_version": RECORD_VERSION,
        "files": files,
        "parent": _parent_entry(parent),
    }
    if version.is_file(MANIFEST_FILE):
        record["manifest"] = {
            "bytes": version.size(MANIFEST_FILE),
            "sha256": sha256_key(version, MANIFEST_FILE),
        }
    record["digest"] = _record_digest(record)
    version.write_bytes(CHECKSUMS_FILE, json_bytes(record))
    return record


def load_record(version_dir: VersionLike) -> dict[str, Any] | None:
    """The parsed ``checksums.json`` of a version, or None when it has none or it is unreadable
    (:func:`check_record` says which)."""
    return _read_record(_version(version_dir))[0]


def _read_record(version: StoreBackend) -> tuple[dict[str, Any] | None, str]:
    """(the parsed checksums.json, "") or (None, why it cannot be used), read with a size and
    a depth limit (:mod:`dancedata.store.untrusted`)."""
    try:
        record = read_json(version, CHECKSUMS_FILE, limit=RECORD_LIMIT)
    except FileNotFoundError:
        return None, "missing"
    except StoreError as exc:
        return None, exc.problem
    if not isinstance(record, dict):
        return None, "unreadable (not a JSON object)"
    return record, ""


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
    """sha256 per stored file, so a file shared by several versions is read once."""

    by_key: dict[Hashable, str]

    @classmethod
    def empty(cls) -> HashCache:
        return cls(by_key={})

    def hashes(self, backend: StoreBackend, keys: list[str]) -> list[str | None]:
        """sha256 of each key (None for a file that vanished), hashing each file once."""
        contents = [backend.content_key(k) for k in keys]
        pending: dict[Hashable, str] = {}
        for content, key in zip(contents, keys, strict=True):
            if content is not None and content not in self.by_key:
                pending.setdefault(content, key)
        digests = _hash_many(backend, list(pending.values()))
        for content, digest in zip(pending, digests, strict=True):
            self.by_key[content] = digest
        return [self.by_key.get(c) if c is not None else None for c in contents]


def _manifest_problems(version: StoreBackend, record: dict[str, Any]) -> list[str]:
    """manifest.json against the ``manifest`` entry of a version-2 record (always re-hashed:
    it is small, and an edited fingerprint or stage list must not pass even a cheap check)."""
    entry = record.get("manifest")
    if not isinstance(entry, dict):
        return []
    try:
        size = version.size(MANIFEST_FILE)
        digest = sha256_key(version, MANIFEST_FILE)
    except OSError:
        return [f"{MANIFEST_FILE}: missing or unreadable"]
    if size != entry.get("bytes") or digest != entry.get("sha256"):
        return [
            f"{MANIFEST_FILE}: differs from the one recorded at commit in {CHECKSUMS_FILE} "
            "(edited after commit: its fingerprint, stages or inputs cannot be trusted)"
        ]
    return []


def _parent_problems(version: StoreBackend, record: dict[str, Any]) -> list[str]:
    """The parent's checksums.json against the hash this version recorded of it."""
    entry = record.get("parent")
    if not isinstance(entry, dict) or not isinstance(entry.get("version"), str):
        return []
    name = entry["version"]
    try:
        digest = sha256_key(version.sibling(name), CHECKSUMS_FILE)
    except OSError:
        return [f"{CHECKSUMS_FILE}: parent {name}'s record is gone (recorded at commit)"]
    if digest != entry.get("checksums_sha256"):
        return [
            f"{CHECKSUMS_FILE}: parent {name}'s {CHECKSUMS_FILE} differs from the one recorded "
            "when this version was committed (the parent's record was rewritten)"
        ]
    return []


def _unrecorded_chunks(version: StoreBackend, files: dict[str, Any]) -> list[str]:
    """Chunks of crc32c arrays (every chunk written) that the record does not list: a record
    built from the files present after a chunk went missing."""
    required, problems = chunk_requirements(version)
    for rel, (_array, grid) in sorted(required.items()):
        if grid.crc32c and rel not in files:
            problems.append(
                f"{describe_file(rel)} ({rel}): required by the array's shape and chunk grid "
                "but not recorded at commit"
            )
    return problems


def check_record(
    version_dir: VersionLike,
    *,
    deep: bool,
    cache: HashCache | None = None,
    sharing: Callable[[StoreBackend, str], str] | None = None,
) -> list[str]:
    """Problems of one committed version against its ``checksums.json``.

    Without ``deep`` only presence, sizes, unrecorded files, symbolic links, required chunks,
    the manifest and the parent's record are checked; with ``deep`` every file is re-hashed. A
    version committed before checksums existed passes the cheap check and fails the deep one
    (there is nothing to verify against).
    """
    version = _version(version_dir)
    links = special_files(version)
    if not version.exists(CHECKSUMS_FILE):
        missing = [f"{CHECKSUMS_FILE}: missing, so the data cannot be verified"] if deep else []
        return links + missing
    record, unreadable = _read_record(version)
    if record is None:
        return [*links, f"{CHECKSUMS_FILE}: {unreadable}"]
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
    shared = sharing or (lambda _v, _rel: "")
    problems: list[str] = [*links]
    problems += _manifest_problems(version, record)
    problems += _parent_problems(version, record)
    problems += _unrecorded_chunks(version, files)
    problems += [
        f"{describe_file(rel)} ({rel}): stored in this version although its references.json "
        f"says {holder} holds it (written after commit; readers read {holder}'s)"
        for rel, holder in sorted(version.shadowed().items())
    ]
    present = data_file_sizes(version)
    for rel in sorted(set(present) - set(files)):
        problems.append(f"{describe_file(rel)} ({rel}): file not recorded at commit")
    checked: list[str] = []
    for rel, entry in sorted(files.items()):
        if rel not in present:
            problems.append(f"{describe_file(rel)} ({rel}): missing")
            continue
        if not version.is_regular(rel):
            continue  # a symbolic link: reported above, never followed
        size = present[rel]
        if size != entry.get("bytes"):
            problems.append(
                f"{describe_file(rel)} ({rel}): {size} bytes, {entry.get('bytes')} recorded at "
                f"commit{shared(version, rel)}"
            )
            continue
        checked.append(rel)
    if deep:
        digests = (cache or HashCache.empty()).hashes(version, checked)
        for rel, digest in zip(checked, digests, strict=True):
            if digest != files[rel].get("sha256"):
                problems.append(
                    f"{describe_file(rel)} ({rel}): sha256 differs from the one recorded at "
                    f"commit (corrupted){shared(version, rel)}"
                )
    return problems


def _sharing_index(
    layout: StoreLayout, versions: Iterable[str]
) -> Callable[[StoreBackend, str], str]:
    """A function telling which other versions hold the same stored file (hard link) as a
    given file (the index is built on first use: only when there is something to report)."""
    owners: dict[Hashable, list[str]] = {}
    names = list(versions)

    def build() -> None:
        for name in names:
            vdir = layout.version_backend(name)
            for rel in data_files(vdir):
                key = vdir.identity(rel)
                if key is not None:
                    owners.setdefault(key, []).append(name)
        names.clear()

    def shared(version: StoreBackend, rel: str) -> str:
        if names:
            build()
        key = version.identity(rel)
        others = [v for v in owners.get(key, []) if v != version.name] if key else []
        if not others:
            return ""
        return f"; the same file (hard link) is in {', '.join(others)}"

    return shared


def verify_store(
    store: str | Path | StoreBackend, versions: list[str], *, deep: bool
) -> dict[str, list[str]]:
    """Problems per version, for the given committed versions of ``store`` (anything
    :class:`StoreLayout` opens: a path, a URL or a backend)."""
    layout = StoreLayout(store)
    cache = HashCache.empty()
    sharing = _sharing_index(layout, layout.committed_versions())
    return {
        name: check_record(layout.version_backend(name), deep=deep, cache=cache, sharing=sharing)
        for name in versions
    }
