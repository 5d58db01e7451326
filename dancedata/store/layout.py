"""Where things live inside a store directory, and the store.json pointer.

A store is a directory::

    STORE/store.json            {"format": "dancedata-store", "format_version": 1, "latest": "v3"}
    STORE/versions/vN/          immutable once committed; committed means manifest.json exists
    STORE/versions/.tmp-*       versions being built; never listed, removed when abandoned
"""

from __future__ import annotations

import json
import os
import re
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
    with open(tmp, "w", encoding="utf-8") as handle:
        json.dump(value, handle, indent=2, sort_keys=True)
        handle.write("\n")
        handle.flush()
        os.fsync(handle.fileno())
    os.replace(tmp, path)
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

    def read_pointer(self) -> dict[str, Any]:
        """Contents of store.json; a clear error when it is missing or not ours."""
        if not self.store_file.is_file():
            raise StoreError("not a dancedata store (no store.json)", self.root)
        try:
            text = self.store_file.read_text(encoding="utf-8")
        except OSError as exc:
            raise StoreError(f"unreadable store.json: {exc}", self.store_file) from None
        return parse_pointer(text, self.store_file)

    def write_pointer(self, latest: str | None) -> None:
        self.root.mkdir(parents=True, exist_ok=True)
        write_json_atomic(
            self.store_file,
            {"format": FORMAT_NAME, "format_version": FORMAT_VERSION, "latest": latest},
        )

    def ensure(self) -> None:
        """Create an empty store (store.json with no latest version) if there is none."""
        if not self.exists():
            if self.root.exists() and any(self.root.iterdir()):
                raise StoreError(
                    "directory exists, is not empty and is not a dancedata store", self.root
                )
            self.versions_dir.mkdir(parents=True, exist_ok=True)
            self.write_pointer(None)
        else:
            self.read_pointer()
            self.versions_dir.mkdir(parents=True, exist_ok=True)

    def committed_versions(self) -> list[str]:
        """Committed version names, oldest first. A version is committed once its directory has
        its final name and holds manifest.json (written last, before the rename)."""
        if not self.versions_dir.is_dir():
            return []
        names = [
            entry.name
            for entry in self.versions_dir.iterdir()
            if _VERSION_RE.match(entry.name) and (entry / MANIFEST_FILE).is_file()
        ]
        return sorted(names, key=version_number)

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
        return newest

    def resolve(self, version: str | None) -> str:
        """The version to read: ``version`` if committed, else the latest; clear errors."""
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
        path = self.version_dir(version) / MANIFEST_FILE
        try:
            return json.loads(path.read_text(encoding="utf-8"))
        except (OSError, json.JSONDecodeError) as exc:
            raise StoreError(f"unreadable manifest: {exc}", path) from None
