"""Clear a store's writer lock by hand (``dancedata unlock``), on any backend.

The lock is ``STORE/.lock`` on every backend (:mod:`dancedata.store.lock` for its record and how
a holder is judged). The store is named as the user gave it: ``s3://bucket/prefix`` stays a URL
(never a ``Path``, which would collapse ``s3://`` to ``s3:/`` and look for a local folder).
"""

from __future__ import annotations

from pathlib import Path

from dancedata.errors import StoreError
from dancedata.store.backend import StoreBackend
from dancedata.store.backend_open import make_backend
from dancedata.store.lock import (
    LOCK_FILE,
    describe_holder,
    judge_holder,
    read_store_holder,
    remove_lock_if,
)


def _remove_if_unchanged(backend: StoreBackend, holder: dict) -> bool:
    """Delete the lock if it still carries ``holder``'s token. A local store does so under the
    lock's flock guard; an object store has no guard, so the record is read again just before
    the delete (a writer that took the lock meanwhile has another token)."""
    root = backend.where()
    if isinstance(root, Path):
        return remove_lock_if(root, holder)
    try:
        current = read_store_holder(backend)
    except StoreError:
        return False
    if current is None or current.get("token") != holder.get("token"):
        return False
    backend.delete(LOCK_FILE)
    return True


def unlock(store: str | Path | StoreBackend, *, force: bool = False) -> str:
    """Clear the store's lock by hand. Stale locks always; a foreign-host or unreadable lock
    only with ``force``; a lock whose holder runs on this host never. Returns what was done,
    naming the store as given."""
    backend = make_backend(store)
    name = backend.describe()
    try:
        holder = read_store_holder(backend)
    except StoreError:
        if not force:
            raise
        backend.delete(LOCK_FILE)
        return f"removed unreadable lock file {backend.where(LOCK_FILE)}"
    if holder is None:
        return f"{name} is not locked"
    state = judge_holder(holder)
    if state.status == "live":
        raise StoreError(f"lock is held by a running writer, {describe_holder(holder)}", name)
    if state.status == "foreign" and not force:
        raise StoreError(
            f"lock is {state.reason} ({describe_holder(holder)}); this host cannot tell whether "
            "it still runs. Pass --force once you know it is dead",
            name,
        )
    if not _remove_if_unchanged(backend, holder):
        return f"{name}: the lock changed hands meanwhile; nothing removed"
    return f"removed the lock of {describe_holder(holder)} ({state.reason})"
