"""Stores on object storage and other fsspec filesystems (``s3://bucket/prefix``, ...).

Same layout and contract as a local store; what differs is how a version is committed, since
object stores have no atomic rename of a directory:

1. The version is built under ``versions/.tmp-<fingerprint[:16]>/`` (workers write there).
2. ``manifest.json`` is written; every object is copied server-side to ``versions/vN/``, and the
   manifest is copied last.
3. ``store.json`` is rewritten to name ``vN``: **this single PUT is the commit point.**
4. The temporary prefix is deleted.

Readers resolve versions through ``store.json``: a version is committed when its manifest exists
and its number is at most the one ``store.json`` names. A writer that dies anywhere before step
3 leaves nothing a reader can see (the next writer removes the leftovers); one that dies after it
has committed. S3 (and its compatible servers) give strong read-after-write consistency for
single objects, which is all this relies on; readers that list a version mid-copy never do so
because the pointer does not name it yet.

The writer lock is ``STORE/.lock`` created with a conditional PUT (``If-None-Match: *``), which
S3 and moto honour. Where a filesystem does not support exclusive creation the lock falls back
to check-then-write, which two writers starting in the same instant could both pass: run one
writer per remote store. A lock left by a dead writer on this host is taken over; a lock from
another host is never judged stale (remove it with care).
"""

from __future__ import annotations

import contextlib
import io
import json
import re
import sys
import time
from pathlib import Path
from typing import TYPE_CHECKING, Any

from dancedata.errors import StoreError
from dancedata.store.build import BUILD_DIR, PREPARED_FILE, BuildArea
from dancedata.store.fs import remote_fs, zarr_store
from dancedata.store.layout import (
    MANIFEST_FILE,
    STORE_FILE,
    TABLE_FILES,
    TEMP_PREFIX,
    VERSIONS_DIR,
    ZARR_DIR,
    StoreLayout,
    checkout_newest,
    parse_manifest,
    parse_pointer,
    pointer_with_latest,
    version_number,
)
from dancedata.store.lock import LOCK_FILE, describe_holder, holder_is_stale, this_holder
from dancedata.store.writer import VersionWriter

if TYPE_CHECKING:
    import pyarrow as pa
    import zarr

_VERSION_RE = re.compile(r"^v(\d+)$")


class RemoteLayout(StoreLayout):
    """Paths and pointer of a store at an fsspec URL. Paths are URLs (strings)."""

    def __init__(self, root: str | Path) -> None:
        self.url = str(root).rstrip("/")
        self.root = self.url  # type: ignore[assignment]  # a URL, used in messages
        self.fs, self.base = remote_fs(self.url)

    def key(self, *parts: str) -> str:
        """Filesystem path (no protocol) of ``parts`` under the store."""
        return "/".join((self.base, *parts))

    def url_of(self, *parts: str) -> str:
        return "/".join((self.url, *parts))

    @property
    def store_file(self) -> str:  # type: ignore[override]
        return self.url_of(STORE_FILE)

    @property
    def versions_dir(self) -> str:  # type: ignore[override]
        return self.url_of(VERSIONS_DIR)

    def version_dir(self, name: str) -> str:  # type: ignore[override]
        version_number(name)
        return self.url_of(VERSIONS_DIR, name)

    def exists(self) -> bool:
        self.fs.invalidate_cache()
        return bool(self.fs.isfile(self.key(STORE_FILE)))

    def read_pointer(self) -> dict[str, Any]:
        try:
            text = self.fs.cat_file(self.key(STORE_FILE))
        except FileNotFoundError:
            raise StoreError("not a dancedata store (no store.json)", self.url) from None
        return parse_pointer(text, self.store_file)

    def write_pointer(self, latest: str | None) -> None:
        """One PUT: atomic, and the commit point of a remote version. Other fields of
        store.json (the checkout log) are kept."""
        current = None
        if self.exists():
            with contextlib.suppress(StoreError):
                current = self.read_pointer()
        self.write_pointer_record(pointer_with_latest(current, latest))

    def write_pointer_record(self, pointer: dict[str, Any]) -> None:
        body = json.dumps(pointer, indent=2, sort_keys=True) + "\n"
        self.fs.pipe_file(self.key(STORE_FILE), body.encode())

    def ensure(self) -> None:
        if self.exists():
            self.read_pointer()
            return
        if self.fs.exists(self.base) and self.fs.ls(self.base, detail=False):
            raise StoreError("prefix exists, is not empty and is not a dancedata store", self.url)
        self.write_pointer(None)

    def committed_versions(self) -> list[str]:
        """Versions with a manifest whose number is at most the one store.json names."""
        if not self.exists():
            return []
        pointer = self.read_pointer()
        latest = pointer.get("latest")
        if latest is None:
            return []
        # after `dancedata checkout` latest may be older than versions committed before it:
        # the checkout log records the newest one it saw, which stays committed
        limit = max(version_number(latest), checkout_newest(pointer))
        found = self.fs.glob(self.key(VERSIONS_DIR, "v*", MANIFEST_FILE))
        names = {p.rstrip("/").split("/")[-2] for p in found}
        return sorted(
            (n for n in names if _VERSION_RE.match(n) and version_number(n) <= limit),
            key=version_number,
        )

    def latest(self) -> str | None:
        """store.json's version: on object stores the pointer is the commit record."""
        committed = self.committed_versions()
        if not committed:
            return None
        named = self.read_pointer().get("latest")
        return named if named in committed else committed[-1]

    def temp_dirs(self) -> list[str]:  # type: ignore[override]
        return [
            self.url_of(VERSIONS_DIR, name)
            for name in self._children(VERSIONS_DIR)
            if name.startswith(TEMP_PREFIX)
        ]

    def _children(self, *parts: str) -> list[str]:
        self.fs.invalidate_cache()
        prefix = self.key(*parts)
        if not self.fs.exists(prefix):
            return []
        return sorted(p.rstrip("/").split("/")[-1] for p in self.fs.ls(prefix, detail=False))

    def read_manifest(self, version: str) -> dict[str, Any]:
        path = self.key(VERSIONS_DIR, version, MANIFEST_FILE)
        try:
            text = self.fs.cat_file(path)
        except OSError as exc:
            raise StoreError(f"unreadable manifest: {exc}", self.url_of(path)) from None
        return parse_manifest(text, self.url_of(path))

    # -- reading files of a version ------------------------------------------------------------
    def has_file(self, version: str, rel: str) -> bool:
        return bool(self.fs.isfile(self.key(VERSIONS_DIR, version, rel)))

    def read_bytes(self, version: str, rel: str) -> bytes:
        return self.fs.cat_file(self.key(VERSIONS_DIR, version, rel))

    def zarr_location(self, version: str) -> str:
        return self.url_of(VERSIONS_DIR, version, ZARR_DIR)


class RemoteLock:
    """``STORE/.lock`` on an object store, created by a conditional PUT."""

    def __init__(self, layout: RemoteLayout, *, wait: bool, timeout_s: float = 24 * 3600.0):
        self.layout = layout
        self.path = layout.key(LOCK_FILE)
        self.wait = wait
        self.timeout_s = timeout_s
        self.record: dict[str, Any] | None = None

    def _create(self, record: dict[str, Any]) -> bool:
        body = json.dumps(record).encode()
        fs = self.layout.fs
        try:
            fs.pipe_file(self.path, body, mode="create")
            return True
        except FileExistsError:
            return False
        except (TypeError, NotImplementedError, ValueError):
            pass  # no exclusive create here: check, write, read back (best effort)
        if fs.exists(self.path):
            return False
        fs.pipe_file(self.path, body)
        return self._holder() == record

    def _holder(self) -> dict[str, Any] | None:
        try:
            return json.loads(self.layout.fs.cat_file(self.path))
        except FileNotFoundError:
            return None
        except ValueError:
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
                self.layout.fs.rm(self.path)
                continue
            who = describe_holder(holder) if holder else "an unreadable lock record"
            if not self.wait:
                raise StoreError(
                    f"store is locked by another writer ({who}); rerun with --wait to queue",
                    self.layout.url,
                )
            if time.monotonic() > deadline:
                raise StoreError(f"gave up waiting for the lock held by {who}", self.layout.url)
            if not announced:
                print(f"waiting for the store lock held by {who} ...", file=sys.stderr)
                announced = True
            time.sleep(0.5)

    def release(self) -> None:
        if self.record is None:
            return
        if self._holder() == self.record:
            self.layout.fs.rm(self.path)
        self.record = None


class RemoteVersionWriter(VersionWriter):
    """:class:`VersionWriter` for a remote store (same API; see the module docstring)."""

    layout: RemoteLayout

    def __init__(self, store: str | Path, **kwargs: Any) -> None:
        super().__init__(store, **kwargs)
        self._lock = kwargs.get("lock") or RemoteLock(
            self.layout, wait=kwargs.get("wait_for_lock", False)
        )

    @property
    def fs(self) -> Any:
        return self.layout.fs

    def _tmp_key(self, *parts: str) -> str:
        return "/".join((self.layout.key(VERSIONS_DIR, Path(str(self.tmp)).name), *parts))

    def __enter__(self) -> RemoteVersionWriter:
        self.layout.ensure()
        self._lock.acquire()
        try:
            name = self.temp_name()
            for url in self.layout.temp_dirs():
                other = url.rsplit("/", 1)[-1]
                if other != name:
                    self.fs.rm(self.layout.key(VERSIONS_DIR, other), recursive=True)
                    self.cleaned_temps.append(other)
            self.tmp = self.layout.url_of(VERSIONS_DIR, name)  # type: ignore[assignment]
            if self.resumable and self.fs.isfile(self._tmp_key(BUILD_DIR, PREPARED_FILE)):
                self.resumed = True
                return self
            self._remove_prefix(self._tmp_key())
            if self.parent is not None and self.carry_over:
                self._copy_prefix(
                    self.layout.key(VERSIONS_DIR, self.parent),
                    self._tmp_key(),
                    skip_top={MANIFEST_FILE, "checksums.json", *self.drop},
                )
        except BaseException:
            self._discard()
            raise
        return self

    def _remove_prefix(self, key: str) -> None:
        self.fs.invalidate_cache()
        if self.fs.exists(key):
            self.fs.rm(key, recursive=True)

    def _copy_prefix(self, src: str, dst: str, *, skip_top: set[str] = frozenset()) -> None:
        """Server-side copy of every object under ``src`` to ``dst`` (top-level names in
        ``skip_top`` left out)."""
        self.fs.invalidate_cache()
        sources = [
            p for p in self.fs.find(src) if p[len(src) + 1 :].split("/", 1)[0] not in skip_top
        ]
        if sources:
            self.fs.copy(sources, [dst + p[len(src) :] for p in sources])

    def _discard(self, exc: object = None) -> None:
        if self.tmp is not None and not self._keep_for_resume(exc):
            # best effort: the next writer removes leftovers
            with contextlib.suppress(Exception):
                self._remove_prefix(self._tmp_key())
        self._lock.release()

    def zarr_group(self) -> zarr.Group:
        if self._zarr_group is None:
            import zarr

            self._zarr_group = zarr.open_group(
                store=zarr_store(f"{self.tmp}/{ZARR_DIR}"), mode="a", zarr_format=3
            )
        return self._zarr_group

    def remove_array(self, name: str) -> None:
        key = self._tmp_key(ZARR_DIR, name)
        self.fs.invalidate_cache()
        if self.fs.exists(key):
            self.fs.rm(key, recursive=True)
            self._zarr_group = None

    def write_table(self, name: str, table: pa.Table) -> str:  # type: ignore[override]
        import pyarrow.parquet as pq

        if name not in TABLE_FILES:
            raise StoreError(f"unknown table {name!r}; known: {sorted(TABLE_FILES)}")
        buffer = io.BytesIO()
        pq.write_table(table, buffer, compression="zstd")
        self.fs.pipe_file(self._tmp_key(TABLE_FILES[name]), buffer.getvalue())
        return f"{self.tmp}/{TABLE_FILES[name]}"

    def build_area(self) -> BuildArea:
        return BuildArea(str(self.tmp))

    def reset_outputs(self) -> None:
        self.fs.invalidate_cache()
        prefix = self._tmp_key()
        if not self.fs.exists(prefix):
            return
        for path in self.fs.ls(prefix, detail=False):
            if path.rstrip("/").rsplit("/", 1)[-1] != BUILD_DIR:
                self.fs.rm(path, recursive=True)
        self._zarr_group = None

    def commit(self, counts: dict[str, Any] | None = None) -> str:
        if self.committed_as is not None:
            return self.committed_as
        self._remove_prefix(self._tmp_key(BUILD_DIR))
        self.fs.invalidate_cache()
        if self.fs.exists(self._tmp_key(ZARR_DIR)):
            import warnings

            import zarr

            with warnings.catch_warnings():
                warnings.simplefilter("ignore", category=UserWarning)
                zarr.consolidate_metadata(zarr_store(f"{self.tmp}/{ZARR_DIR}"))
        committed = self.layout.committed_versions()
        name = f"v{version_number(committed[-1]) + 1 if committed else 1}"
        final = self.layout.key(VERSIONS_DIR, name)
        self._remove_prefix(final)  # an earlier writer's copy that never reached the pointer
        manifest = self.manifest(name, counts)
        self._copy_prefix(self._tmp_key(), final)
        self.fs.pipe_file(f"{final}/{MANIFEST_FILE}", json.dumps(manifest, indent=2).encode())
        self.layout.write_pointer(name)  # the commit point
        self.committed_as = name
        self._remove_prefix(self._tmp_key())
        self.tmp = self.layout.url_of(VERSIONS_DIR, name)  # type: ignore[assignment]
        self._lock.release()
        return name
