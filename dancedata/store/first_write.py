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
from dancedata.store.backend import StoreBackend
from dancedata.store.layout import STORE_FILE, VERSIONS_DIR, StoreLayout


@contextmanager
def remove_store_if_left_empty(store: str | Path | StoreBackend) -> Iterator[None]:
    """Run the block; if it raises and the store did not exist before it, remove the empty
    store the block created (see the module docstring), then re-raise."""
    layout = StoreLayout(store)
    try:
        existed = layout.exists()
        folder_existed = layout.backend.exists("")
    except (OSError, StoreError):
        existed = folder_existed = True  # cannot tell: touch nothing
    try:
        yield
    except BaseException:
        if not existed:
            with contextlib.suppress(OSError, StoreError, ValueError):
                _remove_empty_store(layout, remove_folder=not folder_existed)
        raise


def _remove_empty_store(layout: StoreLayout, *, remove_folder: bool) -> None:
    if not layout.exists() or layout.read_pointer().get("latest") is not None:
        return
    backend = layout.backend
    if backend.list_dir(VERSIONS_DIR):
        return  # a resumable build, or anything else: keep it
    if any(name not in {STORE_FILE, VERSIONS_DIR} for name in backend.list_dir("")):
        return  # a lock held by another writer, or someone else's file
    backend.delete(STORE_FILE)
    backend.remove_empty_dir(VERSIONS_DIR)
    if remove_folder:
        backend.remove_empty_dir("")
