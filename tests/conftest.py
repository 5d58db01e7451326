"""Shared fixtures. Real public files come from ../shared/data/real or $DANCEDATA_REAL_DATA.

Tests that use them are marked ``real_data``; they skip only when the folder is absent, and under
``CI=true`` a missing folder is a failure, because CI always has it.
"""

from __future__ import annotations

import atexit
import os
import shutil
import tempfile
from collections.abc import Iterator
from pathlib import Path

import pytest

# numba's on-disk cache of compiled functions (librosa's gufuncs, our kernels) breaks when two
# processes compile the same function into it at once (a segfault on every later call, numba
# issue 10128). Each pytest-xdist worker, and every command its tests start, gets a cache folder
# of its own, set before anything imports numba. The folder is kept between runs (compiling
# librosa's beat tracker and our kernels costs a worker about a minute of CPU, once per machine
# instead of once per run) and held under an exclusive lock for the whole session, so a second
# session running at the same time takes the next folder or, failing that, a temporary one.
# An empty folder is first seeded from the machine's cache (what ``make pipeline``, any
# ``dancedata featurize`` or ``dancedata cache warm`` compiled), so it compiles only the rest.
_NUMBA_LOCKS: list = []


def _numba_cache_of_this_worker() -> str:
    """``$XDG_CACHE_HOME/dancedata/test-numba/<xdist worker>[-k]`` (``~/.cache`` when unset),
    locked for this process; a temporary folder when none can be locked or made."""
    import fcntl

    base = Path(os.environ.get("XDG_CACHE_HOME") or Path.home() / ".cache")
    base = base / "dancedata" / "test-numba"
    worker = os.environ.get("PYTEST_XDIST_WORKER", "main")
    for name in (worker, *(f"{worker}-{k}" for k in range(1, 4))):
        try:
            (base / name).mkdir(parents=True, exist_ok=True)
            lock = open(base / f"{name}.lock", "w")  # noqa: SIM115 - held until the process ends
        except OSError:
            break
        try:
            fcntl.flock(lock, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except OSError:
            lock.close()
            continue
        _NUMBA_LOCKS.append(lock)
        return str(base / name)
    folder = tempfile.mkdtemp(prefix="dancedata-tests-numba-")
    atexit.register(shutil.rmtree, folder, True)
    return folder


def _seeded(folder: str) -> str:
    """``folder``, first filled from the machine's numba cache when it holds nothing."""
    from dancedata.exec.numba_cache import numba_cache_base, seed_cache_folder, seed_sources

    machine = numba_cache_base()  # NUMBA_CACHE_DIR as the user set it, else ~/.cache/...
    seed_cache_folder(Path(folder), seed_sources(machine))
    return folder


os.environ["NUMBA_CACHE_DIR"] = _seeded(_numba_cache_of_this_worker())


def _pin_threads_of_this_worker() -> None:
    """Under pytest-xdist, each of the N workers (and every command or pool it starts, which
    inherit the variables) runs its BLAS, OpenMP, numba and torch pools on cores / N threads,
    at least one, so two workers on two cores do not each run two-thread pools (four busy
    threads on two cores). Its effect on the suite's time was within this machine's noise;
    the two-worker featurize test still takes 16 s alone and up to ~120 s beside OpenUnmix."""
    workers = int(os.environ.get("PYTEST_XDIST_WORKER_COUNT", "0"))
    if workers < 2:
        return
    from dancedata.exec.threads import pin_threads

    pin_threads(max(1, (os.cpu_count() or 1) // workers))


_pin_threads_of_this_worker()

_DEFAULT_REAL = Path(__file__).resolve().parents[1].parent / "shared" / "data" / "real"


@pytest.fixture(scope="session", autouse=True)
def feature_cache_dir(tmp_path_factory) -> Iterator[Path]:
    """Every test (and every CLI subprocess it starts) uses one fresh feature cache for the
    session, never the user's ~/.cache/dancedata/features."""
    root = tmp_path_factory.mktemp("feature-cache")
    saved = os.environ.get("DANCEDATA_CACHE")
    os.environ["DANCEDATA_CACHE"] = str(root)
    yield root
    if saved is None:
        os.environ.pop("DANCEDATA_CACHE", None)
    else:
        os.environ["DANCEDATA_CACHE"] = saved


@pytest.fixture(autouse=True)
def loud_progress() -> Iterator[None]:
    """``--quiet`` and ``--json`` set a process-wide flag; a command run in-process by one test
    must not silence the progress and notes another test reads."""
    from dancedata.progress import set_quiet

    set_quiet(False)
    yield
    set_quiet(False)


def real_data_root() -> Path:
    return Path(os.environ.get("DANCEDATA_REAL_DATA", _DEFAULT_REAL))


@pytest.fixture(scope="session")
def real_data() -> Path:
    """Root of the real public test files; skips (or fails under CI) when absent."""
    root = real_data_root()
    if not root.is_dir():
        if os.environ.get("CI", "").lower() == "true":
            pytest.fail(f"CI=true but the real data folder is missing: {root}")
        pytest.skip(f"real data folder absent: {root}")
    return root


@pytest.fixture(scope="session")
def small_featurized_store(tmp_path_factory) -> Path:
    """A real 2-sequence synthetic AIST++ store: v1 ingest, v2 featurize (offline stems, NMFD),
    v3 segment (tests/viz_helpers.py). Shared by the plot and report tests: never write to it;
    copy it first."""
    from tests.viz_helpers import build_small_store

    return build_small_store(tmp_path_factory.mktemp("small-store"))
