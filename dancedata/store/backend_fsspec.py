"""A store on object storage or another fsspec filesystem (``s3://bucket/prefix``, ...).

Same layout and contract as a local store; what differs is how a version is committed, since
object stores have no atomic rename of a folder (``renames_atomically`` is False):

1. The version is built under ``versions/.tmp-*/`` (workers write there).
2. ``manifest.json`` and ``checksums.json`` are written there; every object is copied
   server-side to ``versions/vN/``, the manifest last (:meth:`FsspecBackend.publish`).
3. ``store.json`` is rewritten to name ``vN``: **this single PUT is the commit point.**
4. The temporary prefix is deleted.

Readers resolve versions through ``store.json``: a version is committed when its manifest exists
and its number is at most the one ``store.json`` names. A writer that dies anywhere before step
3 leaves nothing a reader can see (the next writer removes the leftovers); one that dies after it
has committed. S3 (and its compatible servers) give strong read-after-write consistency for
single objects, which is all this relies on.

The writer lock is ``STORE/.lock`` created with a conditional PUT (``If-None-Match: *``), which
S3 and moto honour. Where a filesystem does not support exclusive creation the lock falls back
to check-then-write, which two writers starting in the same instant could both pass: run one
writer per remote store. A lock left by a dead writer on this host is taken over; a lock from
another host is never judged stale (remove it with care).

Credentials and endpoints come from the protocol's usual environment (see
:mod:`dancedata.store.fs`).
"""

from __future__ import annotations

import errno
import json
import sys
import time
from collections.abc import Hashable, Iterable
from typing import Any

from dancedata.errors import StoreError
from dancedata.store.backend import Bytes, StoreBackend, base_name, join, parent_key
from dancedata.store.fs import remote_fs, storage_options
from dancedata.store.lock import LOCK_FILE, describe_holder, holder_is_stale, this_holder
from dancedata.store.references import (
    REFERENCES_FILE,
    ReferencedVersion,
    parse_references,
    references_body,
)
from dancedata.store.untrusted import LOCK_LIMIT, RECORD_LIMIT


class FsspecBackend(StoreBackend):
    """A store rooted at an fsspec URL. Keys map to ``<bucket/prefix>/<key>``."""

    renames_atomically = False

    def __init__(self, url: str, _fs: Any = None) -> None:
        self.url = str(url).rstrip("/")
        if _fs is None:
            self.fs, self.base = remote_fs(self.url)
        else:
            self.fs, self.base = _fs, _strip_protocol(self.url)

    def __repr__(self) -> str:
        return f"FsspecBackend({self.url!r})"

    def __eq__(self, other: object) -> bool:
        return isinstance(other, FsspecBackend) and other.url == self.url

    def __hash__(self) -> int:
        return hash(self.url)

    def __getstate__(self) -> dict[str, Any]:
        return {"url": self.url}  # the filesystem is rebuilt from the URL and the environment

    def __setstate__(self, state: dict[str, Any]) -> None:
        self.__init__(state["url"])  # type: ignore[misc]

    def key(self, key: str) -> str:
        """Filesystem path (no protocol) of a store key."""
        return f"{self.base}/{key}" if key else self.base

    def where(self, key: str = "") -> str:
        return f"{self.url}/{key}" if key else self.url

    def describe(self) -> str:
        return self.url

    def locator(self, key: str = "") -> str:
        return self.where(key)

    def at(self, key: str) -> FsspecBackend:
        return FsspecBackend(self.where(key), _fs=self.fs) if key else self

    def sibling(self, name: str) -> FsspecBackend:
        return FsspecBackend(f"{self.url.rsplit('/', 1)[0]}/{name}", _fs=self.fs)

    def invalidate(self) -> None:
        self.fs.invalidate_cache()

    # -- reading -------------------------------------------------------------------------------
    def read_bytes(self, key: str) -> bytes:
        # start=0: one GET. Without a range s3fs first asks the object's size (a HEAD) to
        # decide on a concurrent download, which only pays for objects of tens of MB.
        try:
            return self.fs.cat_file(self.key(key), start=0)
        except OSError as exc:
            if exc.errno != errno.EINVAL:  # an empty object: a range of it is unsatisfiable
                raise
        return self.fs.cat_file(self.key(key))

    def read_small(self, key: str, limit: int) -> bytes:
        """One ranged GET of at most ``limit + 1`` bytes; more than ``limit`` came back, the
        object is refused, its size then asked for the message. Untrusted: what the server
        sends is counted, whatever size it declares."""
        from dancedata.store.untrusted import too_large

        path = self.key(key)
        try:
            data = self.fs.cat_file(path, start=0, end=limit + 1)
        except OSError as exc:
            if exc.errno != errno.EINVAL:
                raise
            return super().read_small(key, limit)  # an empty object (no range of it exists)
        if len(data) > limit:
            raise too_large(self.where(key), max(len(data), self.size(key)), limit)
        return data

    def is_file(self, key: str) -> bool:
        # not fs.isfile: fsspec's swallows every error, so a dead endpoint or missing
        # credentials read as "no such file" ("not a dancedata store")
        try:
            return self.fs.info(self.key(key)).get("type") == "file"
        except FileNotFoundError:
            return False

    def is_dir(self, key: str) -> bool:
        self.fs.invalidate_cache()
        return bool(self.fs.isdir(self.key(key)))

    def exists(self, key: str) -> bool:
        self.fs.invalidate_cache()
        return bool(self.fs.exists(self.key(key)))

    def list_dir(self, key: str) -> list[str]:
        self.fs.invalidate_cache()
        prefix = self.key(key)
        try:
            entries = self.fs.ls(prefix, detail=False)
        except FileNotFoundError:
            return []
        own = prefix.rstrip("/")
        return sorted({p.rstrip("/").rsplit("/", 1)[-1] for p in entries if p.rstrip("/") != own})

    def find(self, key: str, *, skip_top: Iterable[str] = ()) -> list[str]:
        self.fs.invalidate_cache()
        prefix = self.key(key).rstrip("/")
        skip = set(skip_top)
        found = []
        for path in self.fs.find(prefix):
            rel = path[len(prefix) + 1 :]
            if rel and rel.split("/", 1)[0] not in skip:
                found.append(rel)
        return sorted(found)

    def size(self, key: str) -> int:
        return int(self.fs.size(self.key(key)))

    def file_sizes(self, key: str, *, skip_top: Iterable[str] = ()) -> dict[str, int]:
        """One listing (sizes come with it), not one request per file."""
        self.fs.invalidate_cache()
        prefix = self.key(key).rstrip("/")
        skip = set(skip_top)
        found = {}
        for path, info in self.fs.find(prefix, detail=True).items():
            rel = path[len(prefix) + 1 :]
            if rel and rel.split("/", 1)[0] not in skip:
                found[rel] = int(info.get("size") or 0)
        return dict(sorted(found.items()))

    def identity(self, key: str) -> Hashable | None:
        return None  # every key is its own object: a copy is never "the same file"

    def content_key(self, key: str) -> Hashable | None:
        try:
            info = self.fs.info(self.key(key))
        except OSError:
            return None
        etag = info.get("ETag") or info.get("etag") or info.get("md5Hash")
        return ("etag", str(etag).strip('"'), info.get("size")) if etag else None

    # -- writing -------------------------------------------------------------------------------
    def write_bytes(self, key: str, data: Bytes | Iterable[Bytes], *, durable: bool = True) -> None:
        """One PUT: atomic on object stores."""
        if not isinstance(data, bytes | bytearray | memoryview):
            data = b"".join(bytes(piece) for piece in data)
        self.fs.pipe_file(self.key(key), bytes(data))

    def create_exclusive(self, key: str, data: bytes) -> bool | None:
        try:
            self.fs.pipe_file(self.key(key), data, mode="create")
            return True
        except FileExistsError:
            return False
        except (TypeError, NotImplementedError, ValueError):
            return None

    def delete(self, key: str) -> None:
        self.fs.invalidate_cache()
        path = self.key(key)
        if self.fs.exists(path):
            self.fs.rm(path, recursive=True)

    def _copy(self, pairs: list[tuple[str, str]]) -> None:
        if pairs:
            self.fs.copy([self.key(s) for s, _ in pairs], [self.key(d) for _, d in pairs])

    def version_view(self, key: str) -> StoreBackend:
        refs = self._references(key)
        version = self.at(key)
        return ReferencedVersion(version, refs) if refs else version

    def _references(self, version: str) -> dict[str, str]:
        """The references.json of a committed version folder ({} when it has none)."""
        try:
            data = self.read_small(join(version, REFERENCES_FILE), RECORD_LIMIT)
        except FileNotFoundError:
            return {}
        except OSError as exc:
            where = self.where(join(version, REFERENCES_FILE))
            problem = f"unreadable {REFERENCES_FILE}: {exc.strerror or exc}"
            raise StoreError(problem, where) from None
        return parse_references(data, self.where(join(version, REFERENCES_FILE)))

    def _stored(self, version: str, *, skip_top: Iterable[str] = ()) -> dict[str, Any]:
        """{rel: (ETag, size)} of the objects physically under a folder, from one listing."""
        self.fs.invalidate_cache()
        prefix = self.key(version).rstrip("/")
        skip = set(skip_top)
        found: dict[str, Any] = {}
        for path, info in self.fs.find(prefix, detail=True).items():
            rel = path[len(prefix) + 1 :]
            if rel and rel.split("/", 1)[0] not in skip:
                etag = info.get("ETag") or info.get("etag")
                found[rel] = (str(etag).strip('"') if etag else None, info.get("size"))
        return found

    def _physical(self, version: str, *, skip_top: Iterable[str] = ()) -> dict[str, str]:
        """{rel: key of the object holding it} for every file of a committed version folder,
        its references resolved (references.json itself left out)."""
        skip = set(skip_top)
        held = {
            rel: join(version, rel)
            for rel in self.find(version, skip_top=skip)
            if rel != REFERENCES_FILE
        }
        versions_dir = parent_key(version)
        for rel, holder in self._references(version).items():
            if rel.split("/", 1)[0] not in skip:
                held[rel] = join(versions_dir, holder, rel)
        return held

    def carry_over(self, src: str, dst: str, *, skip_top: Iterable[str] = ()) -> None:
        """Server-side copy of every file of the committed version ``src`` (top-level names in
        ``skip_top`` left out), wherever its references say it is stored."""
        held = self._physical(src, skip_top=skip_top)
        self._copy([(source, join(dst, rel)) for rel, source in sorted(held.items())])

    def publish(
        self, tmp: str, final: str, *, leave_out: str, last: str, base: str | None = None
    ) -> None:
        """Copy ``tmp`` to ``final`` server-side, ``last`` (the manifest) last; an earlier
        writer's copy that never reached the pointer is removed first. A file whose ETag and
        size equal those of the parent ``base``'s file at the same path is not copied but
        named in ``final/references.json`` (with the version that holds it). ``tmp`` stays
        until the caller deletes it after the pointer PUT."""
        self.delete(final)
        built = self._stored(tmp, skip_top=[leave_out])
        refs = self._unchanged(built, base, last) if base is not None else {}
        copies = [
            (join(tmp, rel), join(final, rel)) for rel in built if rel != last and rel not in refs
        ]
        self._copy(copies)
        if refs:
            self.write_bytes(join(final, REFERENCES_FILE), references_body(refs))
        if last in built:
            self._copy([(join(tmp, last), join(final, last))])

    def _unchanged(self, built: dict[str, Any], base: str, last: str) -> dict[str, str]:
        """{rel: holding version} of the built files whose bytes the parent already holds."""
        versions_dir, parent = parent_key(base), base_name(base)
        base_refs = self._references(base)
        listings: dict[str, dict[str, Any]] = {}

        def stored_in(version: str) -> dict[str, Any]:
            if version not in listings:
                listings[version] = self._stored(join(versions_dir, version))
            return listings[version]

        refs: dict[str, str] = {}
        for rel, (etag, size) in built.items():
            if rel in (last, REFERENCES_FILE) or etag is None:
                continue
            holder = base_refs.get(rel, parent)
            if stored_in(holder).get(rel) == (etag, size):
                refs[rel] = holder
        return refs

    def writer_lock(self, *, wait: bool) -> ObjectStoreLock:
        return ObjectStoreLock(self, wait=wait)

    # -- zarr ----------------------------------------------------------------------------------
    def zarr_store(self, key: str, *, read_only: bool = False) -> Any:
        from zarr.storage import FsspecStore

        options = storage_options()
        if self.url.split("://", 1)[0] in ("s3", "s3a"):
            # A chunk is one GET: with more than one transfer per file allowed, s3fs asks
            # each object's size first (a HEAD) to decide on a concurrent download, which
            # pays only for objects of tens of MB; our chunks are a few MB at most.
            options.setdefault("max_concurrency", 1)
        return FsspecStore.from_url(
            self.where(key), storage_options=options or None, read_only=read_only
        )


def _strip_protocol(url: str) -> str:
    return url.split("://", 1)[1].rstrip("/") if "://" in url else url.rstrip("/")


class ObjectStoreLock:
    """``STORE/.lock`` on an object store, created by a conditional PUT."""

    def __init__(self, backend: FsspecBackend, *, wait: bool, timeout_s: float = 24 * 3600.0):
        self.backend = backend
        self.wait = wait
        self.timeout_s = timeout_s
        self.record: dict[str, Any] | None = None

    @property
    def path(self) -> str:
        return self.backend.key(LOCK_FILE)

    def _create(self, record: dict[str, Any]) -> bool:
        body = json.dumps(record).encode()
        created = self.backend.create_exclusive(LOCK_FILE, body)
        if created is not None:
            return created
        # no exclusive create here: check, write, read back (best effort)
        if self.backend.is_file(LOCK_FILE):
            return False
        self.backend.write_bytes(LOCK_FILE, body)
        return self._holder() == record

    def _holder(self) -> dict[str, Any] | None:
        try:
            return json.loads(self.backend.read_small(LOCK_FILE, LOCK_LIMIT))
        except FileNotFoundError:
            return None
        except (ValueError, RecursionError, OSError):
            return {}

    def acquire(self) -> None:
        if self.record is not None:
            return  # already ours (taken by hold_store_lock before the plan)
        deadline = time.monotonic() + self.timeout_s
        announced = False
        while True:
            record = this_holder()
            if self._create(record):
                self.record = record
                return
            holder = self._holder()
            if holder is None:
                continue  # released meanwhile
            if holder and isinstance(holder.get("pid"), int) and holder_is_stale(holder):
                print(f"took over a stale store lock ({describe_holder(holder)})", file=sys.stderr)
                self.backend.delete(LOCK_FILE)
                continue
            who = describe_holder(holder) if holder else "an unreadable lock record"
            if not self.wait:
                raise StoreError(
                    f"store is locked by another writer ({who}); rerun with --wait to queue",
                    self.backend.url,
                )
            if time.monotonic() > deadline:
                raise StoreError(f"gave up waiting for the lock held by {who}", self.backend.url)
            if not announced:
                print(f"waiting for the store lock held by {who} ...", file=sys.stderr)
                announced = True
            time.sleep(0.5)

    def release(self) -> None:
        if self.record is None:
            return
        if self._holder() == self.record:
            self.backend.delete(LOCK_FILE)
        self.record = None


__all__ = ["FsspecBackend", "ObjectStoreLock"]
