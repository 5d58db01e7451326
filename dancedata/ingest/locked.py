"""The part of an ingest that reads the store, done under the store's writer lock.

No lost update (issue 11, item 3): an ingest that had to wait for the lock must not write the
version it planned before waiting. So, once it holds the lock (:func:`hold_store_lock` with
``create=True``, then ``VersionWriter(lock=...)``), it

* looks again for a committed version carrying its fingerprint (:func:`already_ingested`): a
  writer it waited behind may have just ingested the same data, and then it writes nothing;
* takes the latest version *now* as its parent (:func:`latest_version`), and ``ingest bvh
  --append`` reads the version it appends to only now, so the other writer's version is kept.

Reading the inputs (hashing, decoding) depends on no store state and may happen before the lock.
"""

from __future__ import annotations

from pathlib import Path

from dancedata.store.command_result import CommandResult
from dancedata.store.layout import StoreLayout
from dancedata.store.writer import find_version_with_fingerprint


def latest_version(store: str | Path) -> str | None:
    """The store's latest committed version, None for a new or empty store."""
    layout = StoreLayout(store)
    return layout.latest() if layout.exists() else None


def already_ingested(store: str | Path, fingerprint: str) -> CommandResult | None:
    """A "nothing to do" result when a committed version already holds this ingest's result.

    Authoritative only under the lock. Before it, a version found is still a right answer
    (committed versions never change), so callers may ask first to skip reading inputs; a
    version *not* found must be asked again under the lock.
    """
    existing = find_version_with_fingerprint(store, fingerprint)
    if existing is None:
        return None
    return CommandResult(version=existing, created=False, latest=latest_version(store))
