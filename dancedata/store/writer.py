"""Build a new store version under a temporary name, then commit it with one rename.

Nothing a writer does is visible until :meth:`VersionWriter.commit`: the version is assembled in
``versions/.tmp-<pid>-<token>``, manifest.json is written last, the directory is renamed to
``vN`` (atomic on a local filesystem) and store.json is pointed at it. A crash at any point
leaves the previous versions untouched; the temporary directory is removed by the next writer.

A new version starts as a copy of its parent. Data files (zarr chunks, parquet) are hard-linked,
since committed versions are immutable and zarr replaces files by rename rather than rewriting
them; metadata files are copied so that updating them never touches the parent.

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
import os
import secrets
import shutil
from collections.abc import Iterable, Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import TYPE_CHECKING, Any

from dancedata._version import __version__
from dancedata.errors import DancedataError, StoreError
from dancedata.store.build import BUILD_DIR, PREPARED_FILE, BuildArea
from dancedata.store.fs import is_remote, storage_error
from dancedata.store.integrity import record_checksums
from dancedata.store.layout import (
    MANIFEST_FILE,
    TABLE_FILES,
    TEMP_PREFIX,
    ZARR_DIR,
    StoreLayout,
    fsync_dir,
    write_json_atomic,
)
from dancedata.store.lock import StoreLock

if TYPE_CHECKING:
    import pyarrow as pa
    import zarr

_COPIED_NAMES = {"zarr.json", ".zattrs", ".zgroup", ".zarray", MANIFEST_FILE}


def library_versions() -> dict[str, str]:
    """Versions of the libraries whose output lands in a store."""
    from importlib import metadata

    found = {"dancedata": __version__}
    for name in ("numpy", "scipy", "librosa", "zarr", "pyarrow", "soundfile", "numba"):
        try:
            found[name] = metadata.version(name)
        except metadata.PackageNotFoundError:
            continue
    return found


def _link_or_copy_tree(src: Path, dst: Path, skip: set[str]) -> None:
    """Recreate ``src`` at ``dst``: metadata copied, data files hard-linked (copied when the
    filesystem refuses links). Top-level entries named in ``skip`` are left out."""
    for dirpath, dirnames, filenames in os.walk(src):
        rel = Path(dirpath).relative_to(src)
        if rel == Path("."):
            dirnames[:] = [d for d in dirnames if d not in skip]
            filenames = [f for f in filenames if f not in skip]
        (dst / rel).mkdir(parents=True, exist_ok=True)
        for name in filenames:
            source, target = Path(dirpath) / name, dst / rel / name
            if name in _COPIED_NAMES:
                shutil.copy2(source, target)
                continue
            try:
                os.link(source, target)
            except OSError:
                shutil.copy2(source, target)


def clean_abandoned_temps(layout: StoreLayout, keep: str | None = None) -> list[str]:
    """Remove temporary version directories left by writers that died, except ``keep`` (the
    one a resumable writer is about to reuse). Call under the lock: then no live writer of this
    store owns any of them."""
    removed = []
    for path in layout.temp_dirs():
        if path.name == keep:
            continue
        shutil.rmtree(path, ignore_errors=True)
        removed.append(path.name)
    return removed


@contextmanager
def hold_store_lock(
    store: str | Path, *, wait: bool = False, create: bool = False
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
            error = storage_error(exc, store, "opening the store for writing")
            if error is None:
                raise
            raise error from None
    layout.read_pointer()  # a clear error for a missing store or a file, before any lock file
    if is_remote(store):
        from dancedata.store.remote import RemoteLock

        lock: Any = RemoteLock(layout, wait=wait)  # type: ignore[arg-type]
    else:
        lock = StoreLock(layout.root, wait=wait)
    try:
        try:
            lock.acquire()
        except OSError as exc:
            error = storage_error(exc, store, "taking the store lock")
            if error is None:
                raise
            raise error from None
        yield lock
    except OSError as exc:
        error = storage_error(exc, store, "preparing a new version")
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
        store: str | Path,
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
        self._lock = lock if lock is not None else StoreLock(self.layout.root, wait=wait_for_lock)
        self.tmp: Path | None = None
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

    def __new__(cls, store: str | Path, **kwargs: Any) -> VersionWriter:
        if cls is VersionWriter and is_remote(store):
            from dancedata.store.remote import RemoteVersionWriter

            return super().__new__(RemoteVersionWriter)
        return super().__new__(cls)

    def temp_name(self) -> str:
        """``.tmp-<fingerprint[:16]>`` when resumable, else unique to this process."""
        if self.resumable:
            return f"{TEMP_PREFIX}{self.fingerprint[:16]}"
        return f"{TEMP_PREFIX}{os.getpid()}-{secrets.token_hex(4)}"

    # -- lifecycle -----------------------------------------------------------------------------
    def __enter__(self) -> VersionWriter:
        try:
            self.layout.ensure()
            self._lock.acquire()
        except OSError as exc:
            error = storage_error(exc, self.layout.root, "opening the store for writing")
            if error is None:
                raise
            raise error from None
        try:
            self.existing = find_version_with_fingerprint(self.layout.root, self.fingerprint)
            self._check_based_on()
            name = self.temp_name()
            self.cleaned_temps = clean_abandoned_temps(self.layout, keep=name)
            self.tmp = self.layout.versions_dir / name
            if self.resumable and (self.tmp / BUILD_DIR / PREPARED_FILE).is_file():
                self.resumed = True
                return self
            if self.tmp.exists():
                shutil.rmtree(self.tmp)
            self.tmp.mkdir(parents=True)
            if self.parent is not None and self.carry_over:
                _link_or_copy_tree(
                    self.layout.version_dir(self.parent), self.tmp, {MANIFEST_FILE, *self.drop}
                )
        except BaseException as exc:
            error = storage_error(exc, self.layout.root, "preparing a new version")
            self._discard(error or exc)
            if error is not None:
                raise error from None
            raise
        return self

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
            if self.tmp is not None and self.tmp.exists() and not self._keep_for_resume(exc):
                shutil.rmtree(self.tmp, ignore_errors=True)
        finally:
            self._lock.release()

    # -- resumable builds ----------------------------------------------------------------------
    def build_area(self) -> BuildArea:
        """The temporary version as plain data, for workers to write into."""
        return BuildArea(str(Path(self.path).resolve()))  # absolute: workers may run elsewhere

    def reset_outputs(self) -> None:
        """Delete everything built so far except the build state (``.build``): for commands
        that rewrite all their outputs from finished units on every run (ingest)."""
        for entry in self.path.iterdir():
            if entry.name == BUILD_DIR:
                continue
            if entry.is_dir():
                shutil.rmtree(entry)
            else:
                entry.unlink()
        self._zarr_group = None

    def mark_prepared(self, info: dict[str, Any] | None = None) -> None:
        """Record that the version's arrays exist, pre-sized: a resumed run skips preparing."""
        self.build_area().write_json(PREPARED_FILE, info or {})

    # -- content -------------------------------------------------------------------------------
    @property
    def path(self) -> Path:
        if self.tmp is None:
            raise StoreError("VersionWriter used outside its with-block")
        return self.tmp

    def zarr_group(self) -> zarr.Group:
        """The version's root zarr group (created on first use, with motion/ and audio/)."""
        if self._zarr_group is None:
            import zarr

            self._zarr_group = zarr.open_group(self.path / ZARR_DIR, mode="a", zarr_format=3)
        return self._zarr_group

    def remove_array(self, name: str) -> None:
        """Delete an array (or group) carried over from the parent before replacing it."""
        target = self.path / ZARR_DIR / name
        if target.exists():
            shutil.rmtree(target)
            self._zarr_group = None  # reopen: cached metadata may name the removed node

    def write_table(self, name: str, table: pa.Table) -> Path:
        """Write one of the contract's parquet tables, replacing a carried-over one."""
        import pyarrow.parquet as pq

        if name not in TABLE_FILES:
            raise StoreError(f"unknown table {name!r}; known: {sorted(TABLE_FILES)}")
        target = self.path / TABLE_FILES[name]
        if target.exists():
            target.unlink()  # may be a hard link into the parent: unlink, never overwrite
        pq.write_table(table, target, compression="zstd")
        return target

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
        """Consolidate metadata, write manifest.json, rename into place, move store.json."""
        if self.committed_as is not None:
            return self.committed_as
        if self.existing is not None:
            # Another writer committed this very result while this one waited for the lock.
            self._discard()
            self.committed_as = self.existing
            return self.existing
        zarr_path = self.path / ZARR_DIR
        if zarr_path.exists():
            import warnings

            import zarr

            with warnings.catch_warnings():
                # Consolidated metadata is a zarr-python extension to v3; we write it for fast
                # opens and readers that ignore it still work.
                warnings.simplefilter("ignore", category=UserWarning)
                zarr.consolidate_metadata(str(zarr_path))
        name = self.layout.next_version_name()  # past damaged folders too: never collides
        manifest = self.manifest(name, counts)
        # integrity (issue 8, 11.5): checksums.json of every data file and of the manifest, so
        # the manifest goes first (the directory is invisible until the rename either way)
        write_json_atomic(self.path / MANIFEST_FILE, manifest)
        record_checksums(self.path, self.layout.version_dir(self.parent) if self.parent else None)
        # The finished units' build state stays until the last moment, so a kill anywhere
        # before the commit rename still resumes them; it leaves by one rename of its own.
        spent = None
        if (self.path / BUILD_DIR).exists():
            spent = self.layout.versions_dir / f"{TEMP_PREFIX}spent-{secrets.token_hex(6)}"
            os.rename(self.path / BUILD_DIR, spent)
        final = self.layout.version_dir(name)
        os.rename(self.path, final)
        fsync_dir(self.layout.versions_dir)
        if spent is not None:
            shutil.rmtree(spent, ignore_errors=True)
        self.committed_as = name
        self.tmp = final
        try:
            self.layout.write_pointer(name)  # (a reader finds vN even if this fails)
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
    store: str | Path,
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


def find_version_with_fingerprint(store: str | Path, fingerprint: str) -> str | None:
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
