"""Leave nothing behind when the first command to write a new store fails.

An ingest creates the store (store.json naming no version, an empty versions/) before it holds
the lock and reads its inputs; if it then fails (bad input, a full disk, Ctrl-C), what is left
is a store with no committed version, which ``validate`` calls invalid and which blocks nothing
but confuses everyone. :func:`remove_store_if_left_empty` wraps such a command: when the store
did not exist before and the command fails, it removes what the command created, and only that:
store.json when it still names no version, versions/ when it is empty, and the store folder
when this command created it and it is empty again. A store that holds anything else (a
committed version, a resumable ``.tmp-*`` build kept for the next run, a file someone put
there, a lock of another writer) is left as it is.
"""

from __future__ import annotations

import contextlib
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path

from dancedata.errors import StoreError
from dancedata.store.fs import is_remote
from dancedata.store.layout import STORE_FILE, VERSIONS_DIR, StoreLayout


@contextmanager
def remove_store_if_left_empty(store: str | Path) -> Iterator[None]:
    """Run the block; if it raises and the store did not exist before it, remove the empty
    store the block created (see the module docstring), then re-raise."""
    layout = StoreLayout(store)
    try:
        existed = layout.exists()
        folder_existed = is_remote(store) or Path(store).exists()
    except (OSError, StoreError):
        existed = folder_existed = True  # cannot tell: touch nothing
    try:
        yield
    except BaseException:
        if not existed:
            with contextlib.suppress(OSError, StoreError, ValueError):
                _remove_empty_store(layout, store, remove_folder=not folder_existed)
        raise


def _remove_empty_store(layout: StoreLayout, store: str | Path, *, remove_folder: bool) -> None:
    if not layout.exists() or layout.read_pointer().get("latest") is not None:
        return
    if is_remote(store):
        fs = layout.fs  # type: ignore[attr-defined]
        fs.invalidate_cache()
        if fs.find(layout.key(VERSIONS_DIR)):  # type: ignore[attr-defined]
            return
        others = [
            p for p in fs.ls(layout.base, detail=False)  # type: ignore[attr-defined]
            if p.rstrip("/").rsplit("/", 1)[-1] not in {STORE_FILE, VERSIONS_DIR}
        ]
        if not others:
            fs.rm(layout.key(STORE_FILE))  # type: ignore[attr-defined]
        return
    root = Path(layout.root)
    versions = root / VERSIONS_DIR
    if versions.is_dir() and any(versions.iterdir()):
        return  # a resumable build, or anything else: keep it
    if any(p.name not in {STORE_FILE, VERSIONS_DIR} for p in root.iterdir()):
        return  # a lock held by another writer, or someone else's file
    (root / STORE_FILE).unlink()
    if versions.is_dir():
        versions.rmdir()
    if remove_folder:
        root.rmdir()
