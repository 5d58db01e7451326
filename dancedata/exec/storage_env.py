"""The environment a store is reached through, carried from the client to remote workers.

A store URL (``s3://bucket/prefix``) alone does not say where the store is: the endpoint,
credentials and extra fsspec options come from the environment (``AWS_ENDPOINT_URL``,
``AWS_ACCESS_KEY_ID``, ..., ``DANCEDATA_STORAGE_OPTIONS``; see :mod:`dancedata.store.fs`).
Local worker processes inherit it; workers of a Dask cluster, started elsewhere, do not, and
without it write to a same-named bucket of the public cloud. So the client takes a snapshot
(:func:`storage_env`) that travels with every task, and a worker applies it
(:func:`apply_storage_env`) before running the task.

The snapshot holds credentials: on a network you do not trust, run the cluster over TLS
(``tls://`` addresses), as for any data the tasks carry.
"""

from __future__ import annotations

import os
import sys
from collections.abc import Mapping

from dancedata.store.fs import STORAGE_OPTIONS_ENV

# Variables read by fsspec and the object-store clients it uses (s3fs/botocore, gcsfs, adlfs):
# every variable whose name starts with one of these prefixes, plus the project's own options.
STORAGE_ENV_PREFIXES: tuple[str, ...] = ("AWS_", "FSSPEC_", "GCSFS_", "GOOGLE_", "AZURE_")


def storage_env(environ: Mapping[str, str] | None = None) -> dict[str, str]:
    """The storage variables set in ``environ`` (default: this process's environment)."""
    source = os.environ if environ is None else environ
    return {
        name: value
        for name, value in sorted(source.items())
        if name == STORAGE_OPTIONS_ENV or name.startswith(STORAGE_ENV_PREFIXES)
    }


def apply_storage_env(env: Mapping[str, str]) -> bool:
    """Set ``env`` in this process's environment (worker side). Returns True when it changed
    anything; then fsspec's cached filesystem instances, created under the old values, are
    dropped so that the next store access connects with the new ones.

    Variables the client did not set are left as the worker has them (a worker may hold its own
    credentials, e.g. from an instance role). The environment is process-wide: tasks of one
    client carry the same values, so concurrent tasks on a multi-threaded worker agree.
    """
    changed = {name: value for name, value in env.items() if os.environ.get(name) != value}
    if not changed:
        return False
    os.environ.update(changed)
    _forget_filesystems()
    return True


def _forget_filesystems() -> None:
    """Drop the cached instances of every fsspec filesystem class imported so far."""
    fsspec = sys.modules.get("fsspec")
    if fsspec is None:
        return
    for cls in dict(fsspec.registry).values():
        clear = getattr(cls, "clear_instance_cache", None)
        if clear is not None:
            clear()
