"""``dancedata checkout STORE vN``: make an existing committed version the latest.

Versions are immutable, so going back to an older result is a move of the pointer, not a copy:
under the store's writer lock, store.json's ``latest`` is set to ``vN`` and an entry is
appended to its ``checkouts`` list (the checkout log, never rewritten, only appended to), in
one atomic write (a rename on local stores, a single PUT on object stores).

After a checkout, readers without an explicit version read ``vN``, and the next writer derives
its version from ``vN`` (its ``parent``); the new version gets the next free number past every
existing one, so nothing is renumbered or overwritten. Each log entry records the version
checked out, the latest before it (``previous``), the newest committed version at that moment
(``newest``: on object stores it keeps versions past ``vN`` committed, and on local stores a
version committed later still wins over the checkout), the UTC time and who did it.
"""

from __future__ import annotations

import getpass
import socket
from dataclasses import dataclass
from datetime import UTC, datetime
from pathlib import Path
from typing import Any

from dancedata.errors import StoreError
from dancedata.store.backend import StoreBackend
from dancedata.store.backend_open import make_backend
from dancedata.store.layout import StoreLayout, last_checkout, pointer_with_latest, version_number
from dancedata.store.writer import hold_store_lock

CHECKOUTS_KEY = "checkouts"


def normalize_version(text: str) -> str:
    """``"3"`` or ``"v3"`` → ``"v3"``; StoreError for anything else."""
    name = text.strip()
    if name.isdigit():
        name = f"v{int(name)}"
    version_number(name)
    return name


@dataclass
class CheckoutResult:
    """What ``checkout`` did: ``version`` is now latest; ``previous`` was latest before."""

    version: str
    previous: str | None
    changed: bool
    entry: dict[str, Any] | None

    def message(self, store: str | Path | StoreBackend) -> str:
        if not self.changed:
            return f"checkout: {self.version} is already the latest version of {store}"
        return (
            f"checkout: latest is now {self.version} (was {self.previous}); readers read it by "
            f"default and the next version written derives from it"
        )

    def as_dict(self) -> dict[str, Any]:
        return {
            "command": "checkout",
            "version": self.version,
            "previous": self.previous,
            "changed": self.changed,
            "entry": self.entry,
        }


def _who() -> str:
    try:
        user = getpass.getuser()
    except (KeyError, OSError):
        user = "unknown"
    return f"{user}@{socket.gethostname()}"


def checkout(
    store: str | Path | StoreBackend, version: str, *, wait: bool = False
) -> CheckoutResult:
    """Make committed ``version`` (``"v3"`` or ``"3"``) the latest of ``store``, recorded in the
    checkout log. Checking out the version that is already latest writes nothing."""
    name = normalize_version(version)
    handle = make_backend(store)  # resolved once: the lock and the layout share it
    with hold_store_lock(handle, wait=wait):
        layout = StoreLayout(handle)
        committed = layout.committed_versions()
        if name not in committed:
            layout.resolve(name)  # the reader's error: damaged, or which versions exist
            raise StoreError(f"no committed version {name!r}", layout.root)  # (not reached)
        previous = layout.latest()
        if previous == name:
            return CheckoutResult(name, previous, changed=False, entry=None)
        pointer = layout.read_pointer()
        entry = {
            "version": name,
            "previous": previous,
            "newest": committed[-1],
            "at": datetime.now(UTC).strftime("%Y-%m-%dT%H:%M:%SZ"),
            "by": _who(),
        }
        log = pointer.get(CHECKOUTS_KEY)
        record = pointer_with_latest(pointer, name)
        record[CHECKOUTS_KEY] = [*(log if isinstance(log, list) else []), entry]
        layout.write_pointer_record(record)
    return CheckoutResult(name, previous, changed=True, entry=entry)


def checkout_log(store: str | Path | StoreBackend) -> list[dict[str, Any]]:
    """Every checkout of ``store``, oldest first (entries that are not objects left out)."""
    log = StoreLayout(store).read_pointer().get(CHECKOUTS_KEY)
    return [e for e in log if isinstance(e, dict)] if isinstance(log, list) else []


def switch_hint(store: str | Path | StoreBackend, version: str, latest: str | None) -> str | None:
    """The "how to switch" sentence for a result found in ``version`` while ``latest`` is
    another version; None when ``version`` is the latest or :func:`builds_on` it."""
    if latest is None or latest == version:
        return None
    if builds_on(store, latest, version):
        return None
    return f"run `dancedata checkout {store} {version}` to make it the latest"


def builds_on(store: str | Path | StoreBackend, latest: str, version: str) -> bool:
    """True when ``version`` is an ancestor of ``latest`` (the manifests' ``parent`` chain) and
    no version after it on that chain was written by the same command: then ``latest`` still
    holds ``version``'s result (a re-run ingest under a featurized and segmented latest).
    A later run of the same command (segment with other settings) replaced it: False."""
    layout = StoreLayout(store)
    try:
        command = layout.read_manifest(version).get("command")
        current: object = latest  # a manifest's parent: untrusted, checked to be a name
        seen: set[str] = set()
        while isinstance(current, str) and current not in seen and len(seen) < 10_000:
            seen.add(current)
            manifest = layout.read_manifest(current)
            if manifest.get("command") == command:
                return False
            if manifest.get("parent") == version:
                return True
            current = manifest.get("parent")
    except StoreError:
        return False
    return False


__all__ = [
    "CHECKOUTS_KEY",
    "CheckoutResult",
    "checkout",
    "builds_on",
    "checkout_log",
    "last_checkout",
    "normalize_version",
    "switch_hint",
]
