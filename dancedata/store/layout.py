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

import copy
import re
import sys
from pathlib import Path
from typing import Any

from dancedata.errors import StoreError
from dancedata.store.backend import TEMP_PREFIX, StoreBackend, json_bytes
from dancedata.store.backend_local import write_file_atomic
from dancedata.store.backend_open import make_backend
from dancedata.store.metadata_checks import counts_problem
from dancedata.store.untrusted import MANIFEST_LIMIT, POINTER_LIMIT, parse_json

FORMAT_NAME = "dancedata-store"
FORMAT_VERSION = 1
STORE_FILE = "store.json"
VERSIONS_DIR = "versions"
MANIFEST_FILE = "manifest.json"
ZARR_DIR = "data.zarr"
_VERSION_RE = re.compile(r"^v(\d+)$")
# read_manifest's default: ask the backend for the manifest's content key itself
_ASK: Any = object()

TABLE_FILES = {
    "sequences": "sequences.parquet",
    "music": "music.parquet",
    "measures": "measures.parquet",
    "beats": "beats.parquet",
    "phrases": "phrases.parquet",
    "splits": "splits.parquet",
    "cameras": "cameras.parquet",
    "keyframes": "keyframes.parquet",
    "normalization": "normalization.parquet",
}


def version_number(name: str) -> int:
    """``"v12"`` → 12; raises StoreError for anything else."""
    match = _VERSION_RE.match(name)
    if not match:
        raise StoreError(f"not a version name: {name!r} (expected v1, v2, ...)")
    return int(match.group(1))


def write_json_atomic(path: Path, value: Any) -> None:
    """Write JSON to a local ``path`` through a temporary file, fsync and rename, so readers see
    either the old file or the new one, never a torn one."""
    write_file_atomic(Path(path), json_bytes(value))


def parse_pointer(text: str | bytes, where: str | Path) -> dict[str, Any]:
    """Parse and check the text of a store.json (local or remote); StoreError naming ``where``
    when it is not JSON, not ours, or of a format_version this dancedata does not read."""
    pointer = parse_json(text, where, STORE_FILE)
    if not isinstance(pointer, dict) or pointer.get("format") != FORMAT_NAME:
        raise StoreError("store.json is not a dancedata store pointer", where)
    if pointer.get("format_version") != FORMAT_VERSION:
        raise StoreError(
            f"format_version {pointer.get('format_version')} is not supported "
            f"(this dancedata reads {FORMAT_VERSION})",
            where,
        )
    latest = pointer.get("latest")
    if latest is not None and not (isinstance(latest, str) and _VERSION_RE.match(latest)):
        raise StoreError(
            f"store.json: latest {latest!r:.60} is not a version name (v1, v2, ...) or null", where
        )
    if "checkouts" in pointer and not isinstance(pointer["checkouts"], list):
        raise StoreError("store.json: 'checkouts' must be a list", where)
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
    counts = counts_problem(manifest.get("counts"))
    if counts is not None:
        return f"manifest.json: {counts}"
    return None


def _empty_or_being_created(backend: StoreBackend) -> bool:
    """True when the store root holds nothing, or only what another writer creating a store
    there at this very moment makes before store.json (an empty versions/ folder, store.json's
    temporary file): two ingests started together into a new store must not fail with "not a
    dancedata store"."""
    for name in backend.list_dir(""):
        if name == VERSIONS_DIR and backend.is_dir(name) and not backend.list_dir(name):
            continue
        if name.startswith(f"{TEMP_PREFIX}{STORE_FILE}."):
            continue
        return False
    return True


def parse_manifest(text: str | bytes, where: str | Path) -> dict[str, Any]:
    """Parse and check the text of a manifest.json; StoreError naming ``where`` when it is not
    JSON or not a usable manifest (see :func:`manifest_problem`)."""
    manifest = parse_json(text, where, "manifest")
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
    """Paths and pointer of one store, on any backend (see :mod:`dancedata.store.backend`).
    Knows nothing about arrays or tables. ``root``, ``store_file``, ``versions_dir`` and
    ``version_dir()`` are what messages show: Paths for a local store, URLs otherwise."""

    def __init__(self, root: str | Path | StoreBackend) -> None:
        self.backend = make_backend(root)
        self.root: Any = self.backend.where()

    @property
    def store_file(self) -> Any:
        return self.backend.where(STORE_FILE)

    @property
    def versions_dir(self) -> Any:
        return self.backend.where(VERSIONS_DIR)

    def version_key(self, name: str) -> str:
        """The backend key of ``versions/<name>`` (checked to be a version name)."""
        version_number(name)
        return f"{VERSIONS_DIR}/{name}"

    def version_dir(self, name: str) -> Any:
        return self.backend.where(self.version_key(name))

    def version_backend(self, name: str) -> StoreBackend:
        """The committed version ``versions/<name>`` as a backend rooted there, every file at
        its own path wherever it is stored (see :mod:`dancedata.store.references`)."""
        return self.backend.version_view(self.version_key(name))

    def exists(self) -> bool:
        self.backend.invalidate()
        return self.backend.is_file(STORE_FILE)

    def _missing_pointer(self) -> str:
        """Why there is no store.json: nothing at the path, or a folder that is not a store."""
        noun = self.backend.root_noun
        try:
            present = self.backend.is_dir("")
        except OSError:
            present = True  # cannot tell: say only what is known
        return f"the {noun} has no store.json" if present else f"no such {noun}"

    def check_not_a_file(self) -> None:
        """StoreError when the store path is an existing file rather than a directory."""
        if self.backend.is_file(""):
            raise StoreError("is a file, not a store directory", self.root)

    def read_pointer(self) -> dict[str, Any]:
        """Contents of store.json; a clear error when it is missing or not ours.

        Read first, asked about only when the read fails: on an object store the good case is
        one request (it was five, and every command reads the pointer several times)."""
        special = self.backend.special(STORE_FILE)
        if special is not None:
            raise StoreError(
                f"is {special}, not a regular file (a store holds regular files only; nothing "
                "is read through it)",
                self.store_file,
            )
        try:
            text = self.backend.read_small(STORE_FILE, POINTER_LIMIT)
        except OSError as exc:
            self.check_not_a_file()
            if isinstance(exc, FileNotFoundError) or not self.exists():
                raise StoreError(
                    f"not a dancedata store ({self._missing_pointer()})", self.root
                ) from None
            raise StoreError(
                f"unreadable store.json: {exc.strerror or exc}", self.store_file
            ) from None
        return parse_pointer(text, self.store_file)

    def write_pointer(self, latest: str | None) -> None:
        """Point store.json at ``latest``, keeping its other fields (the checkout log). One
        atomic write (a rename locally, one PUT on object stores, where it is the commit
        point of a version)."""
        self.write_pointer_record(pointer_with_latest(self._pointer_or_none(), latest))

    def write_pointer_record(self, pointer: dict[str, Any]) -> None:
        """Replace store.json with ``pointer`` (already checked), atomically."""
        self.backend.write_bytes(STORE_FILE, json_bytes(pointer))

    def _pointer_or_none(self) -> dict[str, Any] | None:
        try:
            return self.read_pointer()
        except StoreError:  # missing or not ours
            return None

    def ensure(self) -> None:
        """Create an empty store (store.json with no latest version) if there is none."""
        self.check_not_a_file()
        if not self.exists():
            if self.backend.exists("") and not _empty_or_being_created(self.backend):
                raise StoreError(
                    f"{self.backend.root_noun} exists, is not empty and is not a dancedata store",
                    self.root,
                )
            self.backend.make_dir(VERSIONS_DIR)
            if not self.exists():  # (another writer creating it may have finished meanwhile)
                self.write_pointer(None)
        else:
            self.read_pointer()
            self.backend.make_dir(VERSIONS_DIR)

    def version_dirs(self) -> list[str]:
        """Every ``vN`` entry of versions/ that counts, committed or damaged, oldest first.

        Where the pointer is the commit point (object stores), folders numbered past the
        newest version store.json names or has named (its checkout log) do not count: they are
        copies whose writer died before the commit, and the next writer replaces them."""
        special = self.backend.special(VERSIONS_DIR)
        if special is not None:
            raise StoreError(
                f"is {special}, not a folder (a store holds regular files and folders only; "
                "nothing is read through it)",
                self.versions_dir,
            )
        names = [n for n in self.backend.list_dir(VERSIONS_DIR) if _VERSION_RE.match(n)]
        for name in names:
            special = self.backend.special(f"{VERSIONS_DIR}/{name}")
            if special is not None:
                raise StoreError(
                    f"is {special}, not a version folder (a store holds regular files and "
                    "folders only; nothing is read through it)",
                    self.version_dir(name),
                )
        if not self.backend.renames_atomically:
            limit = self._pointer_limit()
            names = [n for n in names if version_number(n) <= limit]
        return sorted(names, key=version_number)

    def _pointer_limit(self) -> int:
        """The newest version number store.json commits (0 when none)."""
        try:
            pointer = self.read_pointer()
        except StoreError:
            if not self.exists():
                return 0
            raise
        latest = pointer.get("latest")
        if not isinstance(latest, str) or not _VERSION_RE.match(latest):
            return 0
        # after `dancedata checkout` latest may be older than versions committed before it:
        # the checkout log records the newest one it saw, which stays committed
        return max(version_number(latest), checkout_newest(pointer))

    def version_problem(self, name: str) -> str | None:
        """Why ``versions/<name>`` is not a usable committed version, or None when it is."""
        key = self.version_key(name)
        manifest = f"{key}/{MANIFEST_FILE}"
        # One look at the manifest (on object stores one HEAD, whose ETag keys the parsed-manifest
        # cache): a content key means a file; without one, ask whether it is a file at all.
        content = self.backend.content_key(manifest)
        if content is None and not self.backend.is_file(manifest):  # (a folder: ask no more)
            if not self.backend.is_dir(key):
                return "not a directory"
            return "version folder has no manifest.json (a damaged or half-restored version)"
        try:
            self.read_manifest(name, content=content)
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
        its final name and holds a valid manifest.json (written last, before the rename; on
        object stores, once store.json names it too). Damaged ``vN`` folders are left out,
        each with a one-line warning on stderr."""
        names = []
        for name in self.version_dirs():
            problem = self.version_problem(name)
            if problem is None:
                names.append(name)
            else:
                warn_once(f"{self.version_dir(name)}: ignored, {problem}")
        return names

    def next_version_name(self) -> str:
        """The name of the next version: one past every ``vN`` entry that counts, damaged
        ones included, so a commit never collides with a folder that is already there."""
        taken = self.version_dirs()
        return f"v{version_number(taken[-1]) + 1 if taken else 1}"

    def latest(self, committed: list[str] | None = None) -> str | None:
        """The newest committed version. store.json names it; if a crash fell between the
        commit rename and the pointer update, the newest committed directory wins.
        ``committed``: :meth:`committed_versions` when the caller has just listed them."""
        pointer = self.read_pointer()
        if committed is None:
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
        if version is not None and version in self.version_dirs():
            problem = self.version_problem(version)
            if problem is not None:
                raise StoreError(f"version {version} is damaged: {problem}", self.root)
        committed = self.committed_versions()
        if version is None:
            latest = self.latest(committed)
            if latest is None:
                damaged = self.damaged_versions()
                if damaged:  # name why, so the one line (or JSON error) says what is wrong
                    name, problem = damaged[-1]
                    raise StoreError(
                        f"store has no usable committed version: {name} is damaged: {problem}",
                        self.root,
                    )
                raise StoreError("store has no committed version yet", self.root)
            return latest
        if version not in committed:
            listed = ", ".join(committed) or "none"
            raise StoreError(f"no committed version {version!r} (committed: {listed})", self.root)
        return version

    def temp_names(self) -> list[str]:
        """Names of the temporary version folders under versions/ (builds in progress or
        abandoned), sorted."""
        return [n for n in self.backend.list_dir(VERSIONS_DIR) if n.startswith(TEMP_PREFIX)]

    def temp_dirs(self) -> list[Any]:
        return [self.backend.where(f"{VERSIONS_DIR}/{n}") for n in self.temp_names()]

    # -- reading files of a version ------------------------------------------------------------
    def has_file(self, version: str, rel: str) -> bool:
        return self.version_backend(version).is_file(rel)

    def read_bytes(self, version: str, rel: str) -> bytes:
        return self.version_backend(version).read_bytes(rel)

    def read_manifest(self, version: str, content: Any = _ASK) -> dict[str, Any]:
        """The version's manifest.json, checked (:func:`parse_manifest`); StoreError naming the
        file when it is missing, unreadable or not a usable manifest. ``content``: the file's
        :meth:`~dancedata.store.backend.StoreBackend.content_key` when the caller has just
        asked for it (asked here otherwise)."""
        key = f"{self.version_key(version)}/{MANIFEST_FILE}"
        where = self.backend.where(key)
        try:
            if content is _ASK:
                content = self.backend.content_key(key)
            if content is None:
                return parse_manifest(self.backend.read_small(key, MANIFEST_LIMIT), where)
            cache_key = (str(where), content)
            if cache_key not in _MANIFEST_CACHE:
                if len(_MANIFEST_CACHE) > 256:
                    _MANIFEST_CACHE.clear()
                _MANIFEST_CACHE[cache_key] = parse_manifest(
                    self.backend.read_small(key, MANIFEST_LIMIT), where
                )
        except OSError as exc:
            raise StoreError(f"unreadable manifest: {exc.strerror or exc}", where) from None
        return copy.deepcopy(_MANIFEST_CACHE[cache_key])  # callers may change their copy


# Parsed manifests by (where, content key: inode, size and mtime locally, the ETag on object
# stores): listing versions reads each manifest once.
_MANIFEST_CACHE: dict[tuple[str, Any], dict[str, Any]] = {}
