"""Turn anything store-like into a :class:`~dancedata.store.backend.StoreBackend`."""

from __future__ import annotations

from pathlib import Path

from dancedata.store.backend import StoreBackend
from dancedata.store.backend_local import LocalBackend


def make_backend(store: str | Path | StoreBackend) -> StoreBackend:
    """A backend for anything store-like: a backend (returned as is), a ``Path`` or a path
    string (a local directory; a ``file://`` prefix is dropped), or an fsspec URL
    (``s3://bucket/prefix``; needs the ``scale`` extra)."""
    if isinstance(store, StoreBackend):
        return store
    text = str(store)
    if isinstance(store, Path) or "://" not in text or text.startswith("file://"):
        return LocalBackend(Path(text[len("file://") :] if text.startswith("file://") else text))
    from dancedata.store.backend_fsspec import FsspecBackend  # (fsspec imported only here)

    return FsspecBackend(text)
