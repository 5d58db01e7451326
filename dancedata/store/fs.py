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


# -- operating-system failures while writing a store --------------------------------------------
# errno -> what the user is told; these are conditions of the storage, not bugs, so they become
# one line (StoreError) instead of a traceback. Any other OSError is left to propagate.
_STORAGE_ERRNOS = {
    "ENOSPC": "no space left on the device",
    "EDQUOT": "disk quota exceeded",
    "EFBIG": "file too large for this file system (or for this process's file size limit)",
    "EROFS": "the file system is read-only",
    "EACCES": "permission denied",
    "EPERM": "operation not permitted",
    "EIO": "input/output error from the device",
    "ENOTDIR": "a path component is a file, not a directory",
    "EMFILE": "too many open files in this process",
    "ENFILE": "too many open files on this system",
}


def storage_problem(exc: BaseException) -> str | None:
    """``"no space left on the device (ENOSPC)"`` for an OSError that is a condition of the
    storage (full, read-only, no permission, ...), else None.

    pyarrow reports write failures as OSError without an errno, with the C library's message in
    the text; that message is matched too.
    """
    import errno as errno_mod

    if not isinstance(exc, OSError):
        return None
    code = errno_mod.errorcode.get(exc.errno) if isinstance(exc.errno, int) else None
    if code in _STORAGE_ERRNOS:
        return f"{_STORAGE_ERRNOS[code]} ({code})"
    if code is None:
        text = str(exc)
        for name in _STORAGE_ERRNOS:
            number = getattr(errno_mod, name, None)
            if number is not None and os.strerror(number) in text:
                return f"{_STORAGE_ERRNOS[name]} ({name})"
    return None


def storage_error(exc: BaseException, store: str | Path, doing: str) -> StoreError | None:
    """A one-line StoreError naming ``store`` for a storage OSError raised while ``doing``
    (e.g. "writing a new version"); None when ``exc`` is not such an error."""
    problem = storage_problem(exc)
    if problem is None:
        return None
    where = getattr(exc, "filename", None)
    detail = f" at {where}" if where and str(where) != str(store) else ""
    return StoreError(f"{problem} while {doing}{detail}", store)
