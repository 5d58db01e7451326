"""One numba cache folder per worker slot of a process pool.

numba keeps compiled functions on disk (``cache=True``: librosa's gufuncs and our kernels). Its
cache is not safe when two processes compile the same function at the same moment: a cached
gufunc is two files written apart, and a process that meets one file from each writer crashes
with a segmentation fault, then on every later run, until the files are deleted (numba issue
10128). Worker processes of one pool start together and reach the same functions together, so
each worker slot gets a folder of its own; a slot's folder is reused by the next pool, so the
compile is paid once per slot, not once per run.

A slot folder that does not exist yet is first seeded with a copy of the compiled functions
already in the base folder or a sibling slot (:func:`seed_cache_folder`), so a new slot costs a
copy of a few MB instead of ~20 CPU-s of compiling. Copying is safe while another process writes
the source: numba writes each file whole under a temporary name and renames it, the index before
its data file, so a copy holds at worst an index entry whose data file is missing, which numba
treats as a miss and compiles again, as after a killed writer.
"""

from __future__ import annotations

import os
import re
import shutil
import sys
from collections.abc import Callable, Iterable
from pathlib import Path
from typing import Any

ENV_VAR = "NUMBA_CACHE_DIR"

# numba names the folder for the functions of one source folder ``<its name>_<sha1 of its path>``.
_NUMBA_ENTRY = re.compile(r".+_[0-9a-f]{40}")


def numba_cache_base() -> Path:
    """Where the slots' folders go: ``$NUMBA_CACHE_DIR`` when set, else
    ``$XDG_CACHE_HOME/dancedata/numba``, else ``~/.cache/dancedata/numba``."""
    explicit = os.environ.get(ENV_VAR)
    if explicit:
        return Path(explicit).expanduser()
    base = os.environ.get("XDG_CACHE_HOME") or Path.home() / ".cache"
    return Path(base).expanduser() / "dancedata" / "numba"


def use_machine_cache() -> Path | None:
    """Point numba in this process at :func:`numba_cache_base` (``~/.cache/dancedata/numba``)
    unless ``NUMBA_CACHE_DIR`` is set or numba is already imported (it reads the variable once);
    returns the folder, or None when nothing changed. Called by the ``dancedata`` command before
    any import of numba.

    Why: without it numba caches beside each source file (``__pycache__`` in site-packages and
    in dancedata), which the worker slots under the base cannot seed from, so a first
    ``featurize --workers 2`` after serial runs compiled everything again in each worker
    (measured on the 24-sequence demo store: 69 CPU s against 9 for the warm serial run), and
    which a system-wide install cannot write at all. An empty base is first seeded from its
    slots (:func:`seed_cache_folder`)."""
    if os.environ.get(ENV_VAR) or "numba" in sys.modules:
        return None
    folder = numba_cache_base()
    os.environ[ENV_VAR] = str(folder)
    # and the other way: what worker slots compiled serves a first serial run
    seed_cache_folder(folder, seed_sources(folder))
    return folder


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
    seed_cache_folder(folder, seed_sources(Path(base)))
    os.environ[ENV_VAR] = str(folder)
    return str(folder)


def _subfolders(folder: Path, keep: Callable[[str], object]) -> list[Path]:
    """The folders directly in ``folder`` whose name ``keep`` accepts, sorted; none when
    ``folder`` cannot be listed. Links are never followed."""
    try:
        children = list(folder.iterdir())
    except OSError:
        return []
    return sorted(p for p in children if keep(p.name) and p.is_dir() and not p.is_symlink())


def numba_entries(folder: Path) -> list[Path]:
    """numba's own subfolders of a cache folder (``<source folder>_<sha1>``), not the slot
    folders beside them."""
    return _subfolders(folder, _NUMBA_ENTRY.fullmatch)


def _compiled_files(entry: Path) -> int:
    """Index and data files (``*.nbi``, ``*.nbc``) in one numba subfolder."""
    return sum(1 for _ in entry.glob("*.nb[ic]"))


def _count_files(folder: Path) -> int:
    return sum(_compiled_files(entry) for entry in numba_entries(folder))


def _ignore_partial(_: str, names: list[str]) -> list[str]:
    """numba's temporaries (``<file>.tmp.<uid>``) are files still being written: not copied."""
    return [name for name in names if ".tmp." in name]


def seed_cache_folder(target: Path, sources: Iterable[Path]) -> int:
    """Copy the compiled functions of the fullest of ``sources`` into ``target`` when ``target``
    holds none; returns the number of files copied (0 when nothing was to gain or a copy
    failed: numba then compiles, as without seeding). Each numba subfolder is copied under a
    temporary name and renamed into place, so a process reading ``target`` never sees half."""
    if numba_entries(target):
        return 0
    source = max((s for s in sources if s != target), key=_count_files, default=None)
    if source is None or _count_files(source) == 0:
        return 0
    copied = 0
    for entry in numba_entries(source):
        temporary = target / f".seed-{os.getpid()}-{entry.name}"
        try:
            target.mkdir(parents=True, exist_ok=True)
            shutil.copytree(entry, temporary, symlinks=True, ignore=_ignore_partial)
            os.rename(temporary, target / entry.name)
        except OSError:  # a full disk, a folder another seeder renamed in first: compile instead
            shutil.rmtree(temporary, ignore_errors=True)
            continue
        copied += _compiled_files(target / entry.name)
    return copied


def seed_sources(base: Path) -> list[Path]:
    """Where a new slot of ``base`` can take compiled functions from: ``base`` itself (a process
    run with ``NUMBA_CACHE_DIR=base``) and its slot folders (``worker-*``, ``dask-*``)."""
    return [base, *_subfolders(base, lambda name: name.startswith(("worker-", "dask-")))]
