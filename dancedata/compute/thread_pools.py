"""One BLAS / OpenMP thread inside a block, through one threadpoolctl controller per process.

A fresh ``threadpoolctl.threadpool_limits`` finds the pools by walking every shared object the
process has loaded: about 2 ms with numpy, scipy and librosa loaded, more with torch. The serial
engine did that for every task and NMFD and the repetition filter for every track. The
controller is kept instead and made again only when modules were imported since it was made
(a newly imported extension module can bring a new pool), so the pools it limits are still all
of them.
"""

from __future__ import annotations

import sys
from typing import Any

__all__ = ["one_thread", "thread_pools"]

_KEPT: tuple[int, Any] | None = None  # (len(sys.modules) when made, ThreadpoolController)


def thread_pools() -> Any:
    """This process's ``threadpoolctl.ThreadpoolController`` (BLAS and OpenMP libraries)."""
    global _KEPT
    if _KEPT is None or _KEPT[0] != len(sys.modules):
        from threadpoolctl import ThreadpoolController

        controller = ThreadpoolController()
        _KEPT = (len(sys.modules), controller)
    return _KEPT[1]


def one_thread(user_api: str | None = None) -> Any:
    """Context manager: the pools of ``user_api`` ("blas", "openmp"; None: both) run one thread
    inside the block, and get their thread counts back after it."""
    return thread_pools().limit(limits=1, user_api=user_api)
