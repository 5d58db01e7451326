"""Where a store lives: a local directory or an fsspec URL (``s3://bucket/prefix``, ...).

Remote stores need the ``scale`` extra (fsspec plus the protocol's package, e.g. s3fs).
Credentials and endpoints come from the protocol's usual environment (for S3: AWS_ACCESS_KEY_ID,
AWS_SECRET_ACCESS_KEY, AWS_ENDPOINT_URL, ...). Extra fsspec options can be given as JSON in
``DANCEDATA_STORAGE_OPTIONS``, e.g. ``{"client_kwargs": {"region_name": "eu-west-1"}}``; worker
processes inherit the environment, so they reach the same store.
"""

from __future__ import annotations

import json
import os
from pathlib import Path
from typing import Any

from dancedata.errors import StoreError

STORAGE_OPTIONS_ENV = "DANCEDATA_STORAGE_OPTIONS"


def is_remote(store: str | Path) -> bool:
    """True for an fsspec URL other than ``file://`` (a ``Path`` is always local)."""
    if isinstance(store, Path):
        return False
    text = str(store)
    return "://" in text and not text.startswith("file://")


def local_path(store: str | Path) -> Path:
    """A local store's directory (``file://`` prefix removed)."""
    text = str(store)
    return Path(text[len("file://") :] if text.startswith("file://") else text)


def storage_options() -> dict[str, Any]:
    """fsspec options from ``DANCEDATA_STORAGE_OPTIONS`` (JSON object), else none."""
    text = os.environ.get(STORAGE_OPTIONS_ENV, "").strip()
    if not text:
        return {}
    try:
        value = json.loads(text)
    except json.JSONDecodeError as exc:
        raise StoreError(f"{STORAGE_OPTIONS_ENV} is not valid JSON: {exc}") from None
    if not isinstance(value, dict):
        raise StoreError(f"{STORAGE_OPTIONS_ENV} must be a JSON object")
    return value


def remote_fs(url: str) -> tuple[Any, str]:
    """(fsspec filesystem, path without protocol) for a remote store URL."""
    try:
        from fsspec.core import url_to_fs
    except ImportError:
        raise StoreError(
            "remote stores need the 'scale' extra: pip install 'dancedata[scale]'", url
        ) from None
    try:
        fs, path = url_to_fs(url, **storage_options())
    except (ImportError, ValueError) as exc:
        raise StoreError(f"cannot open this store URL: {exc}", url) from None
    return fs, path.rstrip("/")


def zarr_store(location: str | Path, *, read_only: bool = False) -> Any:
    """A zarr v3 store object for a local directory or a remote URL."""
    if is_remote(location):
        from zarr.storage import FsspecStore

        return FsspecStore.from_url(
            str(location), storage_options=storage_options() or None, read_only=read_only
        )
    from zarr.storage import LocalStore

    return LocalStore(str(local_path(location)), read_only=read_only)
