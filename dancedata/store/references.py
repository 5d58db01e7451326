"""Versions that reference their parent's unchanged files instead of holding copies (object
stores).

A local child shares its parent's unchanged files by hard link. Object stores have no links,
so a remote commit used to copy every object of the version. Instead, when a finished version
is published (:meth:`~dancedata.store.backend_fsspec.FsspecBackend.publish`), every file whose
bytes equal those of the parent's file at the same path (same ETag and size) is not copied;
``versions/vN/references.json`` names, for each such file, the version that physically holds
it (always one that holds it itself, never a chain)::

    {"format": "dancedata-references", "format_version": 1,
     "files": {"data.zarr/motion/rotmat/c/0/0/0/0": "v1", "sequences.parquet": "v1", ...}}

It is written before ``manifest.json`` (still copied last), so a version with a manifest has
its references. ``checksums.json`` is computed on the full build, before publishing, so it lists
every file with its hash exactly as on a local store; a reference resolved to other bytes fails
the deep check. :class:`ReferencedVersion` is the version as readers see it: every file listed
and readable at its own path, wherever it is stored; :class:`RedirectingStore` does the same for
zarr.
"""

from __future__ import annotations

import json
import re
from collections.abc import Hashable, Iterable
from typing import Any

from zarr.abc.store import ByteRequest, Store
from zarr.core.buffer import Buffer, BufferPrototype
from zarr.storage import WrapperStore

from dancedata.errors import StoreError
from dancedata.store.backend import Bytes, StoreBackend

REFERENCES_FILE = "references.json"
REFERENCES_FORMAT = "dancedata-references"
_VERSION = re.compile(r"^v\d+$")


def references_body(files: dict[str, str]) -> bytes:
    """The bytes of a references.json naming ``files`` ({path: holding version})."""
    record = {"format": REFERENCES_FORMAT, "format_version": 1, "files": files}
    return (json.dumps(record, indent=2, sort_keys=True) + "\n").encode()


def parse_references(data: bytes, where: Any) -> dict[str, str]:
    """{version-relative path: holding version} of a references.json; StoreError naming it
    when it is not one."""
    from dancedata.store.untrusted import parse_json

    record = parse_json(data, where, REFERENCES_FILE)
    files = record.get("files") if isinstance(record, dict) else None
    if (
        not isinstance(record, dict)
        or record.get("format") != REFERENCES_FORMAT
        or not isinstance(files, dict)
        or not all(isinstance(k, str) and isinstance(v, str) for k, v in files.items())
    ):
        raise StoreError(f"{REFERENCES_FILE} is not a dancedata references record", where)
    for key, holder in files.items():
        # a holder is a sibling version and a key a path inside it: never a way out
        parts = key.split("/")
        if (
            not _VERSION.match(holder)
            or key.startswith("/")
            or any(p in ("", ".", "..") for p in parts)
        ):
            raise StoreError(
                f"{REFERENCES_FILE} names {key!r:.80} held by {holder!r:.40}: a holder must be "
                "a version name (v1, v2, ...) and a file a plain path inside it",
                where,
            )
    return files


class ReferencedVersion(StoreBackend):
    """A committed version folder whose ``references.json`` names files held by other
    versions: read-only, every file at its own path (``references.json`` itself hidden)."""

    def __init__(self, base: StoreBackend, refs: dict[str, str]) -> None:
        self.base = base
        self.refs = refs
        self.renames_atomically = base.renames_atomically
        self.root_noun = base.root_noun

    def __getstate__(self) -> dict[str, Any]:
        return {"base": self.base, "refs": self.refs}

    def __setstate__(self, state: dict[str, Any]) -> None:
        self.__init__(state["base"], state["refs"])  # type: ignore[misc]

    def shadowed(self) -> dict[str, str]:
        stored = self.base.file_sizes("")
        return {rel: holder for rel, holder in self.refs.items() if rel in stored}

    def _holder(self, key: str) -> tuple[StoreBackend, str]:
        version = self.refs.get(key)
        return (self.base.sibling(version), key) if version else (self.base, key)

    def holder_name(self, key: str) -> str:
        """The version that physically holds ``key``."""
        return self.refs.get(key) or self.base.name

    def where(self, key: str = "") -> Any:
        return self.base.where(key)

    def describe(self) -> str:
        return self.base.describe()

    def locator(self, key: str = "") -> str:
        return self.base.locator(key)

    def at(self, key: str) -> StoreBackend:
        prefix = key.rstrip("/") + "/"
        if key and any(k.startswith(prefix) for k in self.refs):
            raise NotImplementedError("address files of a referenced version from its root")
        return self.base.at(key) if key else self

    def sibling(self, name: str) -> StoreBackend:
        return self.base.sibling(name)

    # -- reading -------------------------------------------------------------------------------
    def read_bytes(self, key: str) -> bytes:
        holder, rel = self._holder(key)
        return holder.read_bytes(rel)

    def read_small(self, key: str, limit: int) -> bytes:
        holder, rel = self._holder(key)
        return holder.read_small(rel, limit)

    def special(self, key: str) -> str | None:
        holder, rel = self._holder(key)
        return holder.special(rel)

    def special_below(self, key: str, *, skip_top: Iterable[str] = ()) -> list[tuple[str, str]]:
        return self.base.special_below(key, skip_top=skip_top)

    def sha256(self, key: str) -> str:
        holder, rel = self._holder(key)
        return holder.sha256(rel)

    def is_file(self, key: str) -> bool:
        if key == REFERENCES_FILE:
            return False
        return key in self.refs or self.base.is_file(key)

    def is_dir(self, key: str) -> bool:
        prefix = key.rstrip("/") + "/" if key else ""
        return self.base.is_dir(key) or any(k.startswith(prefix) for k in self.refs)

    def list_dir(self, key: str) -> list[str]:
        prefix = key.rstrip("/") + "/" if key else ""
        names = set(self.base.list_dir(key))
        names.update(k[len(prefix) :].split("/", 1)[0] for k in self.refs if k.startswith(prefix))
        if not key:
            names.discard(REFERENCES_FILE)
        return sorted(names)

    def find(self, key: str, *, skip_top: Iterable[str] = ()) -> list[str]:
        return sorted(self.file_sizes(key, skip_top=skip_top))

    def file_sizes(self, key: str, *, skip_top: Iterable[str] = ()) -> dict[str, int]:
        skip = set(skip_top)
        prefix = key.rstrip("/") + "/" if key else ""
        found = self.base.file_sizes(key, skip_top=skip)
        if not key:
            found.pop(REFERENCES_FILE, None)
        by_holder: dict[str, list[str]] = {}
        for path, version in self.refs.items():
            if path.startswith(prefix) and path[len(prefix) :].split("/", 1)[0] not in skip:
                by_holder.setdefault(version, []).append(path)
        for version, paths in by_holder.items():
            sizes = self.base.sibling(version).file_sizes(key)
            for path in paths:
                rel = path[len(prefix) :]
                if rel in sizes:
                    found[rel] = sizes[rel]
        return dict(sorted(found.items()))

    def size(self, key: str) -> int:
        holder, rel = self._holder(key)
        return holder.size(rel)

    def identity(self, key: str) -> Hashable | None:
        return None

    def content_key(self, key: str) -> Hashable | None:
        holder, rel = self._holder(key)
        return holder.content_key(rel)

    # -- writing: a committed version is immutable ----------------------------------------------
    def _read_only(self) -> StoreError:
        return StoreError("a committed version is read-only", self.where())

    def write_bytes(self, key: str, data: Bytes | Iterable[Bytes], *, durable: bool = True) -> None:
        raise self._read_only()

    def create_exclusive(self, key: str, data: bytes) -> bool | None:
        raise self._read_only()

    def delete(self, key: str) -> None:
        raise self._read_only()

    def carry_over(self, src: str, dst: str, *, skip_top: Iterable[str] = ()) -> None:
        raise self._read_only()

    def publish(
        self, tmp: str, final: str, *, leave_out: str, last: str, base: str | None = None
    ) -> None:
        raise self._read_only()

    def writer_lock(self, *, wait: bool) -> Any:
        raise self._read_only()

    def zarr_store(self, key: str, *, read_only: bool = False) -> Any:
        prefix = key.rstrip("/") + "/"
        holders: dict[str, Any] = {}  # one zarr store per holding version
        redirects = {}
        for path, version in self.refs.items():
            if path.startswith(prefix):
                if version not in holders:
                    holders[version] = self.base.sibling(version).zarr_store(key, read_only=True)
                redirects[path[len(prefix) :]] = holders[version]
        store = self.base.zarr_store(key, read_only=True)
        return RedirectingStore(store, redirects) if redirects else store


class RedirectingStore(WrapperStore):  # type: ignore[type-arg]
    """A read-only zarr store whose listed keys are read from other stores (the versions that
    hold them); every other key from the wrapped one."""

    def __init__(self, store: Store, redirects: dict[str, Store]) -> None:
        super().__init__(store)
        self.redirects = redirects

    def _with_store(self, store: Store) -> RedirectingStore:
        return RedirectingStore(store, self.redirects)

    def __getstate__(self) -> dict[str, Any]:
        return {"store": self._store, "redirects": self.redirects}

    def __setstate__(self, state: dict[str, Any]) -> None:
        self.__init__(state["store"], state["redirects"])  # type: ignore[misc]

    async def get(
        self, key: str, prototype: BufferPrototype, byte_range: ByteRequest | None = None
    ) -> Buffer | None:
        target = self.redirects.get(key)
        if target is not None:
            return await target.get(key, prototype, byte_range)
        return await self._store.get(key, prototype, byte_range)

    async def get_partial_values(
        self, prototype: BufferPrototype, key_ranges: Iterable[tuple[str, ByteRequest | None]]
    ) -> list[Buffer | None]:
        return [await self.get(key, prototype, rng) for key, rng in key_ranges]

    async def exists(self, key: str) -> bool:
        return key in self.redirects or await self._store.exists(key)

    async def list(self) -> Any:
        seen = set(self.redirects)
        for key in sorted(seen):
            yield key
        async for key in self._store.list():
            if key not in seen:
                yield key

    async def list_prefix(self, prefix: str) -> Any:
        seen = {k for k in self.redirects if k.startswith(prefix)}
        for key in sorted(seen):
            yield key
        async for key in self._store.list_prefix(prefix):
            if key not in seen:
                yield key

    async def list_dir(self, prefix: str) -> Any:
        base = prefix.rstrip("/") + "/" if prefix else ""
        seen: set[str] = set()
        for key in self.redirects:
            if key.startswith(base):
                seen.add(key[len(base) :].split("/", 1)[0])
        for name in sorted(seen):
            yield name
        async for name in self._store.list_dir(prefix):
            if name not in seen:
                yield name
