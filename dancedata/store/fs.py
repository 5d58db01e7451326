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
    if url.split("://", 1)[0].lower() in ("s3", "s3a"):
        check_endpoint_answers()
    return fs, path.rstrip("/")


_ANSWERED: set[str] = set()
_PROXY_VARIABLES = (
    "HTTPS_PROXY",
    "HTTP_PROXY",
    "ALL_PROXY",
    "https_proxy",
    "http_proxy",
    "all_proxy",
)


def check_endpoint_answers(*, timeout_s: float = 5.0) -> None:
    """Fail at once, in one line, when the configured S3 endpoint refuses connections or its
    host name does not exist.

    Without this, botocore retries a refused connection four times with exponential backoff
    (about 8 s) before the error reaches us, in every command and every worker. One TCP connect
    per endpoint and process (a few milliseconds) settles it first. Only a definite answer
    fails: a timeout or any other socket error is left to botocore's own retries, and nothing
    is probed when a proxy carries the traffic or the endpoint is AWS's default."""
    endpoint = explicit_endpoint()
    if (
        endpoint is None
        or endpoint in _ANSWERED
        or any(os.environ.get(v) for v in _PROXY_VARIABLES)
    ):
        return
    import socket
    from urllib.parse import urlsplit

    parts = urlsplit(endpoint)
    try:
        port = parts.port or (443 if parts.scheme == "https" else 80)
    except ValueError:
        return  # a malformed port: botocore's own error says more
    if not parts.hostname:
        return
    try:
        with socket.create_connection((parts.hostname, port), timeout=timeout_s):
            pass
    except ConnectionRefusedError:
        raise StoreError(f"cannot reach S3 endpoint {endpoint}: connection refused") from None
    except socket.gaierror as exc:
        if exc.errno == socket.EAI_NONAME:
            raise StoreError(f"cannot reach S3 endpoint {endpoint}: host name not found") from None
        return
    except OSError:
        return
    _ANSWERED.add(endpoint)


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
    """What is wrong with the storage, in one line, when ``exc`` is a condition of the storage
    rather than a bug; else None.

    - An OSError of a full, read-only, forbidden, ... filesystem:
      ``"no space left on the device (ENOSPC)"``. pyarrow reports write failures as OSError
      without an errno, with the C library's message in the text; that message is matched too.
    - An object store that cannot be reached or refuses who we are (botocore's errors, raised
      as they are or as the cause of s3fs's OSError), naming the endpoint:
      ``"cannot reach S3 endpoint http://127.0.0.1:9: connection refused"``,
      ``"no S3 credentials found for endpoint ...: ..."``.
    """
    object_store = _object_store_problem(exc)
    if object_store is not None:
        return object_store
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
    """A one-line StoreError for a storage failure raised while ``doing`` (e.g. "writing a new
    version"): naming ``store`` for a filesystem condition, naming the endpoint (which is what
    is wrong, whatever the store) for an object store that cannot be reached or refuses the
    credentials. None when ``exc`` is not such an error."""
    object_store = _object_store_problem(exc)
    if object_store is not None:
        return StoreError(object_store)
    problem = storage_problem(exc)
    if problem is None:
        return None
    where = getattr(exc, "filename", None)
    detail = f" at {where}" if where and str(where) != str(store) else ""
    return StoreError(f"{problem} while {doing}{detail}", store)


# botocore's names for "the server cannot be reached" and "we have no usable credentials"
_UNREACHABLE = {
    "EndpointConnectionError",
    "ConnectTimeoutError",
    "ConnectionClosedError",
    "ProxyConnectionError",
    "SSLError",
}
_NO_CREDENTIALS = {"NoCredentialsError", "PartialCredentialsError", "CredentialRetrievalError"}
_REFUSED_CREDENTIALS = {
    "InvalidAccessKeyId",
    "SignatureDoesNotMatch",
    "ExpiredToken",
    "InvalidToken",
    "TokenRefreshRequired",
}
_SOCKET_REASONS = {
    "ECONNREFUSED": "connection refused",
    "ETIMEDOUT": "connection timed out",
    "EHOSTUNREACH": "host unreachable",
    "ENETUNREACH": "network unreachable",
    "ECONNRESET": "connection reset",
}


def _chain(exc: BaseException) -> list[BaseException]:
    """``exc`` and the exceptions it was raised from or during, outermost first."""
    found: list[BaseException] = []
    current: BaseException | None = exc
    while current is not None and current not in found and len(found) < 16:
        found.append(current)
        current = current.__cause__ or current.__context__
    return found


def _object_store_problem(exc: BaseException) -> str | None:
    """The one line for an object store that cannot be reached or refuses the credentials
    (see :func:`storage_problem`); None for anything else."""
    for error in _chain(exc):
        kind = type(error)
        if not kind.__module__.startswith(("botocore", "aiobotocore")):
            continue
        name = kind.__name__
        kwargs = getattr(error, "kwargs", None) or {}
        if name in _UNREACHABLE:
            endpoint = _origin(kwargs.get("endpoint_url")) or configured_endpoint()
            return f"cannot reach S3 endpoint {endpoint}: {_socket_reason(error)}"
        if name in _NO_CREDENTIALS:
            return (
                f"no S3 credentials found for endpoint {configured_endpoint()}: set "
                "AWS_ACCESS_KEY_ID and AWS_SECRET_ACCESS_KEY (or AWS_PROFILE)"
            )
        response = getattr(error, "response", None)
        code = (response or {}).get("Error", {}).get("Code") if isinstance(response, dict) else None
        if code in _REFUSED_CREDENTIALS:
            message = (response or {}).get("Error", {}).get("Message") or code
            return (
                f"S3 endpoint {configured_endpoint()} refused the credentials ({code}: {message})"
            )
    return None


def _socket_reason(error: BaseException) -> str:
    """Why a connection failed ("connection refused", ...), from the socket error under a
    botocore error."""
    import errno as errno_mod
    import socket

    for inner in [*_chain(error), *_chain(getattr(error, "kwargs", {}).get("error") or error)]:
        for candidate in (inner, getattr(inner, "os_error", None)):
            if isinstance(candidate, socket.gaierror):
                return "host name not found"
            number = getattr(candidate, "errno", None)
            code = errno_mod.errorcode.get(number) if isinstance(number, int) else None
            if code in _SOCKET_REASONS:
                return _SOCKET_REASONS[code]
    if type(error).__name__ == "ConnectTimeoutError":
        return "connection timed out"
    if type(error).__name__ == "SSLError":
        return "TLS handshake failed"
    return "connection failed"


def _origin(url: Any) -> str | None:
    """``scheme://host:port`` of a request URL (the endpoint, without bucket and key)."""
    if not isinstance(url, str) or "://" not in url:
        return None
    from urllib.parse import urlsplit

    parts = urlsplit(url)
    return f"{parts.scheme}://{parts.netloc}"


def configured_endpoint() -> str:
    """The S3 endpoint this process talks to: ``endpoint_url`` of DANCEDATA_STORAGE_OPTIONS
    (or its ``client_kwargs``), else AWS_ENDPOINT_URL_S3 / AWS_ENDPOINT_URL, else AWS's own."""
    return explicit_endpoint() or "https://s3.amazonaws.com (the AWS default)"


def explicit_endpoint() -> str | None:
    """The S3 endpoint set for this process (see :func:`configured_endpoint`), or None when
    none is set and AWS's own applies."""
    try:
        options = storage_options()
    except StoreError:
        options = {}
    client = options.get("client_kwargs")
    for value in (
        options.get("endpoint_url"),
        client.get("endpoint_url") if isinstance(client, dict) else None,
        os.environ.get("AWS_ENDPOINT_URL_S3"),
        os.environ.get("AWS_ENDPOINT_URL"),
    ):
        if isinstance(value, str) and value.strip():
            return value.strip().rstrip("/")
    return None
