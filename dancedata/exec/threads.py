"""Pin the thread pools of numeric libraries so that N worker processes use N cores, not N²."""

from __future__ import annotations

import contextlib
import os
from collections.abc import Iterator

# Environment variables read by BLAS builds, OpenMP runtimes and numba when they first load.
THREAD_ENV_VARS: tuple[str, ...] = (
    "OMP_NUM_THREADS",
    "OPENBLAS_NUM_THREADS",
    "MKL_NUM_THREADS",
    "BLIS_NUM_THREADS",
    "VECLIB_MAXIMUM_THREADS",
    "NUMEXPR_NUM_THREADS",
    "NUMBA_NUM_THREADS",
)

_PINNED: int | None = None


def thread_env(n_threads: int = 1) -> dict[str, str]:
    """The environment that limits every numeric thread pool to ``n_threads`` threads."""
    return {name: str(n_threads) for name in THREAD_ENV_VARS}


def pin_threads(n_threads: int = 1) -> None:
    """Limit numeric thread pools in this process to ``n_threads`` (idempotent, cheap).

    Call it first thing in a worker process: the environment variables take effect for libraries
    not imported yet; threadpoolctl limits BLAS / OpenMP pools of libraries already loaded;
    torch, when already imported, gets ``set_num_threads``.
    """
    global _PINNED
    if n_threads == _PINNED:
        return
    os.environ.update(thread_env(n_threads))
    try:
        from threadpoolctl import threadpool_limits

        threadpool_limits(limits=n_threads)
    except ImportError:  # threadpoolctl ships with scikit-learn / librosa; optional here
        pass
    import sys

    torch = sys.modules.get("torch")
    if torch is not None:
        torch.set_num_threads(n_threads)
    _PINNED = n_threads


@contextlib.contextmanager
def single_threaded() -> Iterator[None]:
    """BLAS / OpenMP pools limited to one thread inside the block, restored after it.

    Results of BLAS calls (e.g. librosa's mel filterbank product) can depend on the thread
    count in the last bits, so units computed in this process use one thread like those in
    worker processes: then every engine writes the same bytes.
    """
    import sys

    from dancedata.compute.thread_pools import one_thread

    torch = sys.modules.get("torch")
    torch_threads = torch.get_num_threads() if torch is not None else None
    try:
        limits = one_thread()
    except ImportError:  # pragma: no cover - threadpoolctl comes with librosa's dependencies
        limits = contextlib.nullcontext()
    try:
        if torch is not None:
            torch.set_num_threads(1)
        with limits:
            yield
    finally:
        if torch is not None and torch_threads is not None:
            torch.set_num_threads(torch_threads)
