"""Build a new store version under a temporary name, then commit it in one atomic step.

Nothing a writer does is visible until :meth:`VersionWriter.commit`: the version is assembled in
``versions/.tmp-<pid>-<token>``, manifest.json and checksums.json are written, the folder is
published as ``vN`` and store.json is pointed at it. On a local filesystem the publish is one
rename (the commit point); on object stores it is a copy and the store.json PUT is the commit
point (see :mod:`dancedata.store.backend` and :mod:`dancedata.store.backend_fsspec`). A crash at
any point leaves the previous versions untouched; the temporary folder is removed by the next
writer. One class does both: the differences live in the backend.

A new version starts as a copy of its parent (:meth:`StoreBackend.carry_over`). Locally, data
files (zarr chunks, parquet) are hard-linked, since committed versions are immutable and zarr
replaces files by rename rather than rewriting them; metadata files are copied so that updating
them never touches the parent.

No lost update: a command that derives a version from another (featurize, segment) must choose
its parent, compute its fingerprint and check whether its result already exists *while holding
the store lock*, not before waiting for it; otherwise a writer that waited behind another one
commits a child of a version that is no longer the latest, or a second copy of the result the
other one just committed. :func:`hold_store_lock` takes the lock first; the plan is made under it
and handed to :class:`VersionWriter` with ``lock=``. As a last line of defence, a writer that
finds its fingerprint already committed once it holds the lock commits nothing and returns that
version instead (``VersionWriter.existing``).

Storage failures (full disk, read-only file system, no permission; see
:func:`dancedata.store.fs.storage_error`) end the write with one StoreError naming the store,
after the temporary version is removed and the lock released.
"""

from __future__ import annotations

import datetime as _dt
import io
import os
import secrets
from collections.abc import Iterable, Iterator
from contextlib import contextmanager, suppress
from pathlib import Path
from typing import TYPE_CHECKING, Any

from dancedata._version import __version__, installed_version
from dancedata.errors import DancedataError, StoreError
from dancedata.store.backend import StoreBackend, json_bytes
from dancedata.store.build import BUILD_DIR, PREPARED_FILE, BuildArea
from dancedata.store.fs import storage_error
from dancedata.store.integrity import record_checksums
from dancedata.store.layout import (
    MANIFEST_FILE,
    TABLE_FILES,
    TEMP_PREFIX,
    VERSIONS_DIR,
    ZARR_DIR,
    StoreLayout,
)

if TYPE_CHECKING:
    import pyarrow as pa
    import zarr


def library_versions() -> dict[str, str]:
    """Versions of the libraries whose output lands in a store."""
    found = {"dancedata": __version__}
    for name in ("numpy", "scipy", "librosa", "zarr", "pyarrow", "soundfile", "numba"):
        version = installed_version(name)
        if version is not None:
            found[name] = version
    return found


def clean_abandoned_temps(layout: StoreLayout, keep: str | None = None) -> list[str]:
    """Remove temporary version folders left by writers that died, except ``keep`` (the one a
    resumable writer is about to reuse). Call under the lock: then no live writer of this store
    owns any of them."""
    removed = []
    for name in layout.temp_names():
        if name == keep:
            continue
        layout.backend.delete(f"{VERSIONS_DIR}/{name}")
        removed.append(name)
    return removed


def import_before_locking() -> None:
    """Import what pyarrow loads lazily while building tables (pandas, when installed), before
    a writer takes the store lock. Imported later, inside the locked write, a Ctrl-C landing in
    that import left pandas half-initialised, and the interrupted command's cleanup failed with
    an AttributeError traceback instead of saying "interrupted". Commands that only read never
    build a table and skip the 0.2-0.25 s import."""
    with suppress(ImportError):  # pandas is optional
        import pandas  # noqa: F401


@contextmanager
def hold_store_lock(
    store: str | Path | StoreBackend, *, wait: bool = False, create: bool = False
) -> Iterator[Any]:
    """Hold the writer lock of an existing store for the block (local or remote); plan the new
    version inside the block and pass the lock to :class:`VersionWriter` (``lock=``), which
    releases it at commit. ``create``: make an empty store first if there is none (the ingest
    commands). Storage failures become one StoreError naming the store."""
    layout = StoreLayout(store)
    if create:
        try:
            layout.ensure()  # as VersionWriter does before it locks
        except OSError as exc:
            error = storage_error(exc, layout.root, "opening the store for writing")
            if error is None:
                raise
            raise error from None
    layout.read_pointer()  # a clear error for a missing store or a file, before any lock file
    lock = layout.backend.writer_lock(wait=wait)
    import_before_locking()
    try:
        try:
            lock.acquire()
        except OSError as exc:
            error = storage_error(exc, layout.root, "taking the store lock")
            if error is None:
                raise
            raise error from None
        yield lock
    except OSError as exc:
        error = storage_error(exc, layout.root, "preparing a new version")
        if error is None:
            raise
        raise error from None
    finally:
        lock.release()


class VersionWriter:
    """One new version in the making. Use as a context manager::

        with VersionWriter(store_path, command="featurize", config=cfg, inputs=[...]) as v:
            v.zarr_group()["motion"].create_array(...)
            v.write_table("measures", table)
            v.commit(counts={...})

    Leaving the block without :meth:`commit` (or with an exception) discards everything.
    """

    def __init__(
        self,
        store: str | Path | StoreBackend,
        *,
        command: str,
        config: dict[str, Any],
        fingerprint: str,
        inputs: Iterable[dict[str, Any]] = (),
        parent: str | None = None,
        carry_over: bool = True,
        drop: Iterable[str] = (),
        wait_for_lock: bool = False,
        stage: str | None = None,
        parent_stages: dict[str, str] | None = None,
        resumable: bool = False,
        lock: Any = None,
        based_on: str | None = None,
    ) -> None:
        self.layout = StoreLayout(store)
        # Which fingerprint produced each stage of this version's data ("ingest", "featurize",
        # "segment"): the parent's stages plus this command's.
        self.stages = dict(parent_stages or {})
        if stage is not None:
            self.stages[stage] = fingerprint
        self.command = command
        self.config = config
        self.fingerprint = fingerprint
        self.inputs = list(inputs)
        self.parent = parent
        self.carry_over = carry_over
        self.drop = set(drop)
        self.skipped: list[dict[str, str]] = []
        self.cleaned_temps: list[str] = []
        # ``lock``: one the caller already holds (see hold_store_lock); released at commit.
        self.backend = self.layout.backend
        self._lock = lock if lock is not None else self.backend.writer_lock(wait=wait_for_lock)
        # the temporary version: its backend key, and what messages show (a Path or a URL)
        self.tmp_key: str | None = None
        self.tmp: Any = None
        # ``based_on``: the latest version the caller read its data from before taking the lock
        # (ingest bvh --append); if another writer committed meanwhile, refuse rather than
        # silently drop that writer's version (a lost update).
        self.based_on = based_on
        # The committed version that already holds this fingerprint, found under the lock (a
        # writer that waited behind one producing the same result): commit() then adds nothing.
        self.existing: str | None = None
        self.committed_as: str | None = None
        self._zarr_group: zarr.Group | None = None
        # resume (issue 8.1): the temporary directory is named from the fingerprint; a run that
        # finds it prepared (see dancedata.store.build) reuses it and the units it finished.
        self.resumable = resumable
        self.resumed = False

    def temp_name(self) -> str:
        """``.tmp-<fingerprint[:16]>`` when resumable, else unique to this process."""
        if self.resumable:
            return f"{TEMP_PREFIX}{self.fingerprint[:16]}"
        return f"{TEMP_PREFIX}{os.getpid()}-{secrets.token_hex(4)}"

    # -- lifecycle -----------------------------------------------------------------------------
    def __enter__(self) -> VersionWriter:
        import_before_locking()
        try:
            self.layout.ensure()
            self._lock.acquire()
        except OSError as exc:
            error = storage_error(exc, self.layout.root, "opening the store for writing")
            if error is None:
                raise
            raise error from None
        try:
            self.existing = find_version_with_fingerprint(self.backend, self.fingerprint)
            self._check_based_on()
            name = self.temp_name()
            self.cleaned_temps = clean_abandoned_temps(self.layout, keep=name)
            self.tmp_key = f"{VERSIONS_DIR}/{name}"
            self.tmp = self.backend.where(self.tmp_key)
            prepared = f"{self.tmp_key}/{BUILD_DIR}/{PREPARED_FILE}"
            if self.resumable and self.backend.is_file(prepared):
                self._check_build_area()
                self.resumed = True
                return self
            self.backend.delete(self.tmp_key)
            self.backend.make_dir(self.tmp_key)
            if self.parent is not None and self.carry_over:
                self.backend.carry_over(
                    self.layout.version_key(self.parent),
                    self.tmp_key,
                    skip_top={MANIFEST_FILE, *self.drop},
                )
        except BaseException as exc:
            error = storage_error(exc, self.layout.root, "preparing a new version")
            self._discard(error or exc)
            if error is not None:
                raise error from None
            raise
        return self

    def _check_build_area(self) -> None:
        """Before resuming: the build area holds regular files and folders only. A symbolic
        link planted in it (``data.zarr/audio`` pointing elsewhere) would have the resumed run
        write outside the store; it is refused before anything is written, and the area is
        removed like any refused build (a link is unlinked, never followed)."""
        found = self.backend.special_below(self.tmp_key or "")
        if self.tmp_key is not None and self.backend.special(self.tmp_key) is not None:
            found = [("", self.backend.special(self.tmp_key) or "")]
        if found:
            rel, kind = found[0]
            where = self.backend.where(f"{self.tmp_key}/{rel}" if rel else self.tmp_key or "")
            raise StoreError(
                f"the build area of an interrupted run holds {kind} here (a store holds "
                "regular files only); refused before writing anything, and the build area "
                "was removed: run again to start afresh",
                where,
            )

    def _check_based_on(self) -> None:
        if self.based_on is None or self.existing is not None:
            return
        latest = self.layout.latest()
        if latest != self.based_on:
            raise StoreError(
                f"the store changed while this command waited for the lock: it read "
                f"{self.based_on}, the latest version is now {latest}; run it again",
                self.layout.root,
            )

    def __exit__(self, exc_type: object, exc: object, tb: object) -> None:
        error = storage_error(exc, self.layout.root, "writing a new version")  # type: ignore[arg-type]
        if self.committed_as is None:
            self._discard(error or exc)
            if error is not None:
                raise StoreError(
                    f"{error.problem}; nothing was committed, the temporary version was removed",
                    error.path,
                ) from None
        else:
            self._lock.release()
            if error is not None:
                raise StoreError(
                    f"{error.problem} after version {self.committed_as} was committed",
                    error.path,
                ) from None

    def _keep_for_resume(self, exc: object) -> bool:
        """A resumable build survives a crash or interrupt (the next run with the same
        fingerprint reuses it), but not bad input, which would fail the same way again."""
        return self.resumable and exc is not None and not isinstance(exc, DancedataError)

    def _discard(self, exc: object = None) -> None:
        try:
            if self.tmp_key is not None and not self._keep_for_resume(exc):
                try:
                    self.backend.delete(self.tmp_key)
                except Exception:  # best effort: the next writer removes leftovers
                    if self.backend.renames_atomically:
                        raise
        finally:
            self._lock.release()

    # -- resumable builds ----------------------------------------------------------------------
    def _key(self, *parts: str) -> str:
        if self.tmp_key is None:
            raise StoreError("VersionWriter used outside its with-block")
        return "/".join((self.tmp_key, *parts))

    def build_area(self) -> BuildArea:
        """The temporary version as plain data, for workers to write into (absolute: workers
        may run elsewhere)."""
        return BuildArea(self.backend.locator(self._key()))

    def reset_outputs(self) -> None:
        """Delete everything built so far except the build state (``.build``): for commands
        that rewrite all their outputs from finished units on every run (ingest)."""
        for name in self.backend.list_dir(self._key()):
            if name != BUILD_DIR:
                self.backend.delete(self._key(name))
        self._zarr_group = None

    def mark_prepared(self, info: dict[str, Any] | None = None) -> None:
        """Record that the version's arrays exist, pre-sized: a resumed run skips preparing."""
        self.build_area().write_json(PREPARED_FILE, info or {})

    # -- content -------------------------------------------------------------------------------
    @property
    def path(self) -> Any:
        """The temporary version (a Path locally, a URL on object stores)."""
        if self.tmp is None:
            raise StoreError("VersionWriter used outside its with-block")
        return self.tmp

    def zarr_group(self) -> zarr.Group:
        """The version's root zarr group (created on first use, with motion/ and audio/)."""
        if self._zarr_group is None:
            import zarr

            store = self.backend.zarr_store(self._key(ZARR_DIR))
            self._zarr_group = zarr.open_group(store=store, mode="a", zarr_format=3)
        return self._zarr_group

    def remove_array(self, name: str) -> None:
        """Delete an array (or group) carried over from the parent before replacing it."""
        target = self._key(ZARR_DIR, name)
        if self.backend.exists(target):
            self.backend.delete(target)
            self._zarr_group = None  # reopen: cached metadata may name the removed node

    def remove_table(self, name: str) -> None:
        """Leave out a table carried over from the parent (its data no longer fits the new
        version, e.g. frame indices after a change of frame rate)."""
        if name not in TABLE_FILES:
            raise StoreError(f"unknown table {name!r}; known: {sorted(TABLE_FILES)}")
        target = self._key(TABLE_FILES[name])
        if self.backend.exists(target):
            self.backend.delete(target)

    def write_table(self, name: str, table: pa.Table) -> Any:
        """Write one of the contract's parquet tables, replacing a carried-over one (by an
        atomic replace, never writing through a hard link into the parent)."""
        import pyarrow.parquet as pq

        if name not in TABLE_FILES:
            raise StoreError(f"unknown table {name!r}; known: {sorted(TABLE_FILES)}")
        buffer = io.BytesIO()
        pq.write_table(table, buffer, compression="zstd")
        key = self._key(TABLE_FILES[name])
        self.backend.write_bytes(key, buffer.getbuffer(), durable=False)
        return self.backend.where(key)

    def skip(self, path: str | Path, error: str) -> None:
        """Record an input skipped under ``--on-error skip``."""
        self.skipped.append({"path": str(path), "error": error})

    # -- commit --------------------------------------------------------------------------------
    def manifest(self, name: str, counts: dict[str, Any] | None) -> dict[str, Any]:
        """The manifest.json of this version, committed as ``name``."""
        return {
            "format_version": 1,
            "version": name,
            "parent": self.parent,
            "created_at": _dt.datetime.now(_dt.UTC).isoformat(timespec="seconds"),
            "dancedata_version": __version__,
            "command": self.command,
            "config": self.config,
            "fingerprint": self.fingerprint,
            "stages": self.stages,
            "inputs": self.inputs,
            "skipped": self.skipped,
            "libraries": library_versions(),
            "counts": counts or {},
        }

    def commit(self, counts: dict[str, Any] | None = None) -> str:
        """Consolidate metadata, write manifest.json and checksums.json, publish the folder as
        ``vN``, point store.json at it."""
        if self.committed_as is not None:
            return self.committed_as
        if self.existing is not None:
            # Another writer committed this very result while this one waited for the lock.
            self._discard()
            self.committed_as = self.existing
            return self.existing
        zarr_key = self._key(ZARR_DIR)
        if self.backend.is_dir(zarr_key):
            import warnings

            import zarr

            from dancedata.store.reader import check_zarr_metadata

            # the metadata may come from the parent version (hard links): an untrusted store's
            # zarr.json is checked before zarr parses it (depth, size, bounds, attributes)
            check_zarr_metadata(self.backend.at(self._key()))
            with warnings.catch_warnings():
                # Consolidated metadata is a zarr-python extension to v3; we write it for fast
                # opens and readers that ignore it still work.
                warnings.simplefilter("ignore", category=UserWarning)
                zarr.consolidate_metadata(self.backend.zarr_store(zarr_key))
        name = self.layout.next_version_name()  # past damaged folders too: never collides
        manifest = self.manifest(name, counts)
        # integrity (issue 8, 11.5): checksums.json of every data file and of the manifest, so
        # the manifest goes first (the folder is invisible until it is published either way)
        self.backend.write_bytes(self._key(MANIFEST_FILE), json_bytes(manifest))
        parent = self.layout.version_backend(self.parent) if self.parent else None
        record_checksums(self.backend.at(self._key()), parent)
        # The finished units' build state stays until the last moment, so a kill anywhere
        # before the commit still resumes them (see StoreBackend.publish).
        final = self.layout.version_key(name)
        base = self.layout.version_key(self.parent) if self.parent else None
        self.backend.publish(self._key(), final, leave_out=BUILD_DIR, last=MANIFEST_FILE, base=base)
        self.committed_as = name
        # self._key(): the temporary folder's key (self.tmp_key, never None past the checks above)
        spent, self.tmp_key, self.tmp = self._key(), final, self.backend.where(final)
        try:
            self.layout.write_pointer(name)  # (locally a reader finds vN even if this fails)
            self.backend.delete(spent)  # what a copy left behind (object stores)
        finally:
            self._lock.release()
        return name


def base_fingerprint(manifest: dict[str, Any]) -> str:
    """Fingerprint of the ingested data a version derives from (its ``ingest`` stage).

    featurize and segment read only ingested data, so their fingerprints hash this rather than
    the parent's own fingerprint: re-running the pipeline on its own output changes nothing.
    """
    stages = manifest.get("stages") or {}
    return stages.get("ingest") or manifest["fingerprint"]


def already_done(
    store: str | Path | StoreBackend,
    fingerprint: str,
    parent_manifest: dict[str, Any] | None = None,
    stage: str | None = None,
) -> str | None:
    """The committed version that already holds a command's result, if any.

    That is the parent itself when its ``stages`` record this stage with this fingerprint
    (e.g. featurize run again on a version that was featurized the same way and then
    segmented), else any version whose manifest fingerprint equals ``fingerprint``.
    """
    stages = (parent_manifest or {}).get("stages") or {}
    if stage is not None and stages.get(stage) == fingerprint:
        return parent_manifest.get("version")  # type: ignore[union-attr]
    return find_version_with_fingerprint(store, fingerprint)


def find_version_with_fingerprint(store: str | Path | StoreBackend, fingerprint: str) -> str | None:
    """The committed version whose manifest carries ``fingerprint``, if any."""
    layout = StoreLayout(store)
    if not layout.exists():
        return None
    for name in reversed(layout.committed_versions()):
        try:
            if layout.read_manifest(name).get("fingerprint") == fingerprint:
                return name
        except StoreError:
            continue
    return None
