"""One numba cache folder per worker slot of a process pool.

numba keeps compiled functions on disk (``cache=True``: librosa's gufuncs and our kernels). Its
cache is not safe when two processes compile the same function at the same moment: a cached
gufunc is two files written apart, and a process that meets one file from each writer crashes
with a segmentation fault, then on every later run, until the files are deleted (numba issue
10128). Worker processes of one pool start together and reach the same functions together, so
each worker slot gets a folder of its own; a slot's folder is reused by the next pool, so the
compile is paid once per slot, not once per run.
"""

from __future__ import annotations

import os
import sys
from pathlib import Path
from typing import Any

ENV_VAR = "NUMBA_CACHE_DIR"


def numba_cache_base() -> Path:
    """Where the slots' folders go: ``$NUMBA_CACHE_DIR`` when set, else
    ``$XDG_CACHE_HOME/dancedata/numba``, else ``~/.cache/dancedata/numba``."""
    explicit = os.environ.get(ENV_VAR)
    if explicit:
        return Path(explicit).expanduser()
    base = os.environ.get("XDG_CACHE_HOME") or Path.home() / ".cache"
    return Path(base).expanduser() / "dancedata" / "numba"


def slot_cache_dir(base: Path, slot: int) -> Path:
    """The cache folder of worker slot ``slot`` (0-based) under ``base``."""
    if slot < 0:
        raise ValueError("a worker slot is 0 or more")
    return base / f"worker-{slot}"


def use_slot_cache(base: Path, slot: int) -> Path:
    """Point numba in this process at slot ``slot``'s folder. Takes effect only before numba
    is imported (it reads the variable once), which holds in a freshly spawned worker."""
    folder = slot_cache_dir(base, slot)
    os.environ[ENV_VAR] = str(folder)
    return folder


def dask_worker_cache_dir(base: Path, worker_name: object) -> Path:
    """The cache folder of the local Dask worker named ``worker_name`` under ``base``:
    ``dask-<name>``, the name kept to letters, digits, ``-`` and ``_`` (it becomes a path)."""
    safe = "".join(c if c.isalnum() or c in "-_" else "_" for c in str(worker_name))[:64]
    return base / f"dask-{safe or 'worker'}"


def use_dask_worker_cache(base: str, dask_worker: Any = None) -> str:
    """Run on each worker of a local Dask cluster (``Client.run`` passes ``dask_worker``): point
    numba at a folder no other worker writes. Returns the folder, or ``""`` when numba is already
    imported in that worker (it read the variable then, so setting it would not take effect)."""
    if "numba" in sys.modules or dask_worker is None:
        return ""
    folder = dask_worker_cache_dir(Path(base), dask_worker.name)
    os.environ[ENV_VAR] = str(folder)
    return str(folder)
