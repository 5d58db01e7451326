"""Where things live inside a store directory, and the store.json pointer.

A store is a directory::

    STORE/store.json            {"format": "dancedata-store", "format_version": 1, "latest": "v3"}
    STORE/versions/vN/          immutable once committed; committed means manifest.json exists
    STORE/versions/.tmp-*       versions being built; never listed, removed when abandoned

A ``vN`` folder whose manifest.json is missing, unreadable or not a manifest (a damaged store:
a disk error, a hand edit, a half-restored backup) is *damaged*: it is not a committed version,
so readers and writers pass over it with a one-line warning, ``validate`` reports it, and new
versions are numbered past it so that nothing ever collides with it.
"""

from __future__ import annotations

import contextlib
import copy
import json
import os
import re
import sys
from pathlib import Path
from typing import Any

from dancedata.errors import StoreError
from dancedata.store.fs import is_remote, local_path

FORMAT_NAME = "dancedata-store"
FORMAT_VERSION = 1
STORE_FILE = "store.json"
VERSIONS_DIR = "versions"
MANIFEST_FILE = "manifest.json"
ZARR_DIR = "data.zarr"
TEMP_PREFIX = ".tmp-"
_VERSION_RE = re.compile(r"^v(\d+)$")

TABLE_FILES = {
    "sequences": "sequences.parquet",
    "music": "music.parquet",
    "measures": "measures.parquet",
    "splits": "splits.parquet",
    "cameras": "cameras.parquet",
    "keyframes": "keyframes.parquet",
}


def version_number(name: str) -> int:
    """``"v12"`` → 12; raises StoreError for anything else."""
    match = _VERSION_RE.match(name)
    if not match:
        raise StoreError(f"not a version name: {name!r} (expected v1, v2, ...)")
    return int(match.group(1))


def write_json_atomic(path: Path, value: Any) -> None:
    """Write JSON to ``path`` through a temporary file, fsync and rename, so readers see either
    the old file or the new one, never a torn one."""
    tmp = path.with_name(f"{TEMP_PREFIX}{path.name}.{os.getpid()}")
    try:
        with open(tmp, "w", encoding="utf-8") as handle:
            json.dump(value, handle, indent=2, sort_keys=True)
            handle.write("\n")
            handle.flush()
            os.fsync(handle.fileno())
        os.replace(tmp, path)
    except BaseException:
        # a full disk or a kill mid-write: leave no half-written temporary behind
        with contextlib.suppress(OSError):
            tmp.unlink()
        raise
    fsync_dir(path.parent)


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


def parse_pointer(text: str | bytes, where: str | Path) -> dict[str, Any]:
    """Parse and check the text of a store.json (local or remote); StoreError naming ``where``
    when it is not JSON, not ours, or of a format_version this dancedata does not read."""
    try:
        pointer = json.loads(text)
    except ValueError as exc:
        raise StoreError(f"unreadable store.json: {exc}", where) from None
    if not isinstance(pointer, dict) or pointer.get("format") != FORMAT_NAME:
        raise StoreError("store.json is not a dancedata store pointer", where)
    if pointer.get("format_version") != FORMAT_VERSION:
        raise StoreError(
            f"format_version {pointer.get('format_version')} is not supported "
            f"(this dancedata reads {FORMAT_VERSION})",
            where,
        )
    return pointer


def pointer_with_latest(pointer: dict[str, Any] | None, latest: str | None) -> dict[str, Any]:
    """store.json naming ``latest``, with every other field of ``pointer`` (the checkout log,
    fields a newer dancedata added) kept: the pointer contract is additive."""
    record = dict(pointer or {})
    record.update({"format": FORMAT_NAME, "format_version": FORMAT_VERSION, "latest": latest})
    return record


def last_checkout(pointer: dict[str, Any]) -> dict[str, Any] | None:
    """The newest entry of store.json's ``checkouts`` log, or None (no checkout ever, or a log
    that is not a list of objects, which is then ignored)."""
    log = pointer.get("checkouts")
    if not isinstance(log, list) or not log or not isinstance(log[-1], dict):
        return None
    return log[-1]


def checkout_newest(pointer: dict[str, Any]) -> int:
    """The highest version number any checkout saw committed (0 when none): those versions
    stay committed although ``latest`` may now name an older one."""
    log = pointer.get("checkouts")
    numbers = [0]
    for entry in log if isinstance(log, list) else []:
        seen = entry.get("newest") if isinstance(entry, dict) else None
        if isinstance(seen, str) and _VERSION_RE.match(seen):
            numbers.append(version_number(seen))
    return max(numbers)


def checkout_holds(pointer: dict[str, Any], named: str, newest: str) -> bool:
    """Whether store.json's ``latest`` = ``named``, older than the newest committed version
    ``newest``, is a deliberate checkout: the last checkout chose ``named`` and no version was
    committed past the newest one it saw. (A version committed after a checkout whose pointer
    update was lost, a crash between rename and pointer write, still wins.)"""
    entry = last_checkout(pointer)
    if entry is None or entry.get("version") != named:
        return False
    seen = entry.get("newest")
    if not isinstance(seen, str) or not _VERSION_RE.match(seen):
        return False
    return version_number(newest) <= version_number(seen)


# -- manifests ---------------------------------------------------------------------------------
# Fields other code relies on, with the JSON types they must have when present. "fingerprint"
# must also be present: a version without one can be neither a parent nor a cached result.
_MANIFEST_TYPES: dict[str, tuple[type, ...]] = {
    "format_version": (int,),
    "version": (str,),
    "parent": (str, type(None)),
    "command": (str,),
    "fingerprint": (str,),
    "config": (dict,),
    "stages": (dict,),
    "inputs": (list,),
    "skipped": (list,),
    "counts": (dict,),
    "libraries": (dict,),
}
_TYPE_NAMES = {int: "an integer", str: "a string", dict: "an object", list: "a list"}


def manifest_problem(manifest: Any) -> str | None:
    """What makes a parsed manifest.json unusable (wrong shape or field types), or None."""
    if not isinstance(manifest, dict):
        return f"manifest.json is a JSON {type(manifest).__name__}, not an object"
    if "fingerprint" not in manifest:
        return "manifest.json has no 'fingerprint'"
    for key, types in _MANIFEST_TYPES.items():
        if key in manifest and not isinstance(manifest[key], types):
            wanted = " or ".join(_TYPE_NAMES.get(t, "null") for t in types)
            return f"manifest.json: {key!r} must be {wanted}, not {manifest[key]!r:.60}"
    for key in ("inputs", "skipped"):
        for entry in manifest.get(key, []):
            if not isinstance(entry, dict):
                return f"manifest.json: every {key!r} entry must be an object, not {entry!r:.60}"
    stages = manifest.get("stages") or {}
    if not all(isinstance(k, str) and isinstance(v, str) for k, v in stages.items()):
        return "manifest.json: 'stages' must map stage names to fingerprint strings"
    return None


def _empty_or_being_created(root: Path) -> bool:
    """True when ``root`` holds nothing, or only what another writer creating a store there at
    this very moment makes before store.json (an empty versions/ folder, store.json's
    temporary file): two ingests started together into a new store must not fail with "not a
    dancedata store"."""
    for entry in root.iterdir():
        if entry.name == VERSIONS_DIR and entry.is_dir() and not any(entry.iterdir()):
            continue
        if entry.name.startswith(f"{TEMP_PREFIX}{STORE_FILE}."):
            continue
        return False
    return True


def parse_manifest(text: str | bytes, where: str | Path) -> dict[str, Any]:
    """Parse and check the text of a manifest.json; StoreError naming ``where`` when it is not
    JSON or not a usable manifest (see :func:`manifest_problem`)."""
    try:
        manifest = json.loads(text)
    except ValueError as exc:  # JSONDecodeError and UnicodeDecodeError
        raise StoreError(f"unreadable manifest: {exc}", where) from None
    problem = manifest_problem(manifest)
    if problem is not None:
        raise StoreError(problem, where)
    return manifest


_WARNED: set[str] = set()


def warn_once(message: str) -> None:
    """Print ``warning: message`` on stderr, once per process."""
    if message not in _WARNED:
        _WARNED.add(message)
        print(f"warning: {message}", file=sys.stderr, flush=True)


class StoreLayout:
    """Paths and pointer of one local store directory. Knows nothing about arrays or tables."""

    def __new__(cls, root: str | Path) -> StoreLayout:
        # A URL (s3://...) gets the remote layout, whatever the call site (see store.remote).
        if cls is StoreLayout and is_remote(root):
            from dancedata.store.remote import RemoteLayout

            return super().__new__(RemoteLayout)
        return super().__new__(cls)

    def __init__(self, root: str | Path) -> None:
        self.root = local_path(root)

    @property
    def store_file(self) -> Path:
        return self.root / STORE_FILE

    @property
    def versions_dir(self) -> Path:
        return self.root / VERSIONS_DIR

    def version_dir(self, name: str) -> Path:
        version_number(name)
        return self.versions_dir / name

    def exists(self) -> bool:
        return self.store_file.is_file()

    def check_not_a_file(self) -> None:
        """StoreError when the store path is an existing file rather than a directory."""
        if self.root.exists() and not self.root.is_dir():
            raise StoreError("is a file, not a store directory", self.root)

    def read_pointer(self) -> dict[str, Any]:
        """Contents of store.json; a clear error when it is missing or not ours."""
        self.check_not_a_file()
        if not self.store_file.is_file():
            raise StoreError("not a dancedata store (no store.json)", self.root)
        try:
            text = self.store_file.read_text(encoding="utf-8")
        except OSError as exc:
            raise StoreError(f"unreadable store.json: {exc}", self.store_file) from None
        return parse_pointer(text, self.store_file)

    def write_pointer(self, latest: str | None) -> None:
        """Point store.json at ``latest``, keeping its other fields (the checkout log)."""
        self.root.mkdir(parents=True, exist_ok=True)
        write_json_atomic(self.store_file, pointer_with_latest(self._pointer_or_none(), latest))

    def write_pointer_record(self, pointer: dict[str, Any]) -> None:
        """Replace store.json with ``pointer`` (already checked), atomically."""
        write_json_atomic(self.store_file, pointer)

    def _pointer_or_none(self) -> dict[str, Any] | None:
        try:
            return self.read_pointer() if self.exists() else None
        except StoreError:
            return None

    def ensure(self) -> None:
        """Create an empty store (store.json with no latest version) if there is none."""
        self.check_not_a_file()
        if not self.exists():
            if self.root.exists() and not _empty_or_being_created(self.root):
                raise StoreError(
                    "directory exists, is not empty and is not a dancedata store", self.root
                )
            self.versions_dir.mkdir(parents=True, exist_ok=True)
            if not self.exists():  # (another writer creating it may have finished meanwhile)
                self.write_pointer(None)
        else:
            self.read_pointer()
            self.versions_dir.mkdir(parents=True, exist_ok=True)

    def version_dirs(self) -> list[str]:
        """Every ``vN`` entry of versions/, committed or damaged, oldest first."""
        if not self.versions_dir.is_dir():
            return []
        names = [e.name for e in self.versions_dir.iterdir() if _VERSION_RE.match(e.name)]
        return sorted(names, key=version_number)

    def version_problem(self, name: str) -> str | None:
        """Why ``versions/<name>`` is not a usable committed version, or None when it is."""
        folder = self.versions_dir / name
        if not folder.is_dir():
            return "not a directory"
        if not (folder / MANIFEST_FILE).is_file():
            return "version folder has no manifest.json (a damaged or half-restored version)"
        try:
            self.read_manifest(name)
        except StoreError as exc:
            return exc.problem
        return None

    def damaged_versions(self) -> list[tuple[str, str]]:
        """(name, problem) of every ``vN`` folder that is not a usable committed version."""
        found = []
        for name in self.version_dirs():
            problem = self.version_problem(name)
            if problem is not None:
                found.append((name, problem))
        return found

    def committed_versions(self) -> list[str]:
        """Committed version names, oldest first. A version is committed once its directory has
        its final name and holds a valid manifest.json (written last, before the rename).
        Damaged ``vN`` folders are left out, each with a one-line warning on stderr."""
        names = []
        for name in self.version_dirs():
            problem = self.version_problem(name)
            if problem is None:
                names.append(name)
            else:
                warn_once(f"{self.versions_dir / name}: ignored, {problem}")
        return names

    def next_version_name(self) -> str:
        """The name of the next version: one past every ``vN`` entry, damaged ones included,
        so a commit never collides with a folder that is already there."""
        taken = self.version_dirs()
        return f"v{version_number(taken[-1]) + 1 if taken else 1}"

    def latest(self) -> str | None:
        """The newest committed version. store.json names it; if a crash fell between the
        commit rename and the pointer update, the newest committed directory wins."""
        pointer = self.read_pointer()
        committed = self.committed_versions()
        if not committed:
            return None
        named = pointer.get("latest")
        newest = committed[-1]
        if named in committed and version_number(named) >= version_number(newest):
            return named
        if named in committed and checkout_holds(pointer, named, newest):
            return named  # `dancedata checkout` moved latest back; nothing newer since
        return newest

    def resolve(self, version: str | None) -> str:
        """The version to read: ``version`` (``"v3"``, or ``"3"`` for it) if committed, else
        the latest; clear errors."""
        if version is not None and version.strip().isdigit():
            version = f"v{int(version)}"
        local = isinstance(self.versions_dir, Path)  # (remote layouts list differently)
        if local and version is not None and version in self.version_dirs():
            problem = self.version_problem(version)
            if problem is not None:
                raise StoreError(f"version {version} is damaged: {problem}", self.root)
        committed = self.committed_versions()
        if version is None:
            latest = self.latest()
            if latest is None:
                raise StoreError("store has no committed version yet", self.root)
            return latest
        if version not in committed:
            listed = ", ".join(committed) or "none"
            raise StoreError(f"no committed version {version!r} (committed: {listed})", self.root)
        return version

    def temp_dirs(self) -> list[Path]:
        if not self.versions_dir.is_dir():
            return []
        return sorted(p for p in self.versions_dir.iterdir() if p.name.startswith(TEMP_PREFIX))

    # -- reading files of a version (the remote layout overrides these) ------------------------
    def has_file(self, version: str, rel: str) -> bool:
        return (self.version_dir(version) / rel).is_file()

    def read_bytes(self, version: str, rel: str) -> bytes:
        return (self.version_dir(version) / rel).read_bytes()

    def zarr_location(self, version: str) -> str:
        return str(self.version_dir(version) / ZARR_DIR)

    def read_manifest(self, version: str) -> dict[str, Any]:
        """The version's manifest.json, checked (:func:`parse_manifest`); StoreError naming the
        file when it is missing, unreadable or not a usable manifest."""
        path = self.version_dir(version) / MANIFEST_FILE
        try:
            stat = path.stat()
            key = (str(path), stat.st_ino, stat.st_size, stat.st_mtime_ns)
            if key not in _MANIFEST_CACHE:
                if len(_MANIFEST_CACHE) > 256:
                    _MANIFEST_CACHE.clear()
                _MANIFEST_CACHE[key] = parse_manifest(path.read_bytes(), path)
        except OSError as exc:
            raise StoreError(f"unreadable manifest: {exc.strerror or exc}", path) from None
        return copy.deepcopy(_MANIFEST_CACHE[key])  # callers may change their copy


# Parsed manifests by (path, inode, size, mtime): listing versions reads each manifest once.
_MANIFEST_CACHE: dict[tuple[str, int, int, int], dict[str, Any]] = {}
