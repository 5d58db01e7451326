"""One derived version, written once: the preamble every store → new-version command repeats.

``segment`` and ``keyframes`` (and any later command that derives a version from a parent) do
the same steps in the same order: hold the store's writer lock, resolve the parent version (the
latest, as it is once the lock is held, unless one is named), open it, hash the command's config
and data into a fingerprint, return the existing version when that fingerprint is already
committed, else write the new version and commit it. The parent, the fingerprint and the
"already done" check are read under the lock, so a run that waited behind another writer
derives from that writer's result (no lost update).

Usage::

    with derive_version(store, "segment", options.version, options.wait_for_lock) as step:
        fp = step.fingerprint(config, [base_fingerprint(step.reader.manifest)])
        done = step.already_done(fp)
        if done is not None:
            return done
        with step.writer(config, fp) as version:
            ...
"""

from __future__ import annotations

from collections.abc import Iterator
from contextlib import contextmanager
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from dancedata._version import __version__
from dancedata.store.backend import StoreBackend
from dancedata.store.backend_open import make_backend
from dancedata.store.checksums import fingerprint
from dancedata.store.command_result import CommandResult
from dancedata.store.layout import StoreLayout
from dancedata.store.reader import _VersionReader
from dancedata.store.writer import VersionWriter, already_done, hold_store_lock


@dataclass
class DerivedVersion:
    """A command deriving one new version from ``parent``, while ``lock`` is held.

    Attributes:
        store: the store's handle, resolved once by :func:`derive_version` (its ``str`` is
            the path or URL as given).
        command: the command's name; also its stage in the manifest's ``stages``.
        parent: the version the new one derives from.
        reader: that version, open.
        lock: the held writer lock, handed to the :class:`VersionWriter`.
        wait_for_lock: whether the command waits for another writer (recorded by the writer).
    """

    store: StoreBackend
    command: str
    parent: str
    reader: _VersionReader
    lock: Any
    wait_for_lock: bool

    def fingerprint(self, config: dict[str, Any], data: list[str]) -> str:
        """The result's fingerprint: the command, its config, the fingerprints of the data it
        reads (``data``) and the dancedata version."""
        return fingerprint(self.command, config, data, __version__)

    def already_done(self, fp: str) -> CommandResult | None:
        """The existing version holding this result (``created`` False), or None."""
        existing = already_done(self.store, fp, self.reader.manifest, self.command)
        return None if existing is None else CommandResult(version=existing, created=False)

    def writer(self, config: dict[str, Any], fp: str) -> VersionWriter:
        """The new version's writer: derived from the parent (its fingerprint is the one input),
        recorded as this command's stage, committing under the held lock."""
        return VersionWriter(
            self.store,
            command=self.command,
            config=config,
            fingerprint=fp,
            inputs=[
                {"path": self.parent, "bytes": 0, "sha256": self.reader.manifest["fingerprint"]}
            ],
            parent=self.parent,
            wait_for_lock=self.wait_for_lock,
            stage=self.command,
            parent_stages=self.reader.manifest.get("stages"),
            lock=self.lock,
        )


@contextmanager
def derive_version(
    store: str | Path | StoreBackend, command: str, version: str | None, wait_for_lock: bool
) -> Iterator[DerivedVersion]:
    """Hold the store lock for the block and open the parent: ``version``, or the latest one
    as it is once the lock is held."""
    handle = make_backend(store)  # resolved once: lock, parent, reader and writer share it
    with hold_store_lock(handle, wait=wait_for_lock) as lock:
        layout = StoreLayout(handle)
        parent = layout.resolve(version)
        reader = _VersionReader(layout, parent)
        yield DerivedVersion(handle, command, parent, reader, lock, wait_for_lock)
