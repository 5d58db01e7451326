"""glibc malloc settings for dancedata's command processes and pool workers.

Ingest and featurize move gigabytes through buffers of a few MB to tens of MB (read pickles,
zarr chunks and their compressed bytes, built in zarr's codec threads). With glibc's defaults
each codec thread gets its own arena, arenas and the top of the heap are handed back to the
kernel as soon as they are free, and buffers above the (dynamic, at most 32 MB) mmap threshold
are mapped afresh every time: the next buffer then costs the kernel a page fault and a zeroed
page per 4 kB. On the full AIST++ twin that was about 5 of ingest's 11 system CPU seconds.
One arena, an mmap threshold of 64 MB and up to 256 MB of free heap kept let those buffers be
reused instead (freed memory above that still goes back). Values and stores do not change.
"""

from __future__ import annotations

import ctypes
import ctypes.util
import sys

# mallopt parameters (glibc malloc.h)
_M_TRIM_THRESHOLD = -1
_M_MMAP_THRESHOLD = -3
_M_ARENA_MAX = -8

ARENA_MAX = 1
MMAP_THRESHOLD_BYTES = 64 * 2**20
TRIM_THRESHOLD_BYTES = 256 * 2**20

_done = False


def tune_malloc() -> bool:
    """Apply the settings above to this process (once; best before it starts threads).
    False where there is no glibc ``mallopt`` (other platforms and C libraries): nothing
    changes there."""
    global _done
    if _done:
        return True
    if not sys.platform.startswith("linux"):
        return False
    try:
        libc = ctypes.CDLL(ctypes.util.find_library("c") or "libc.so.6")
        mallopt = libc.mallopt
        gnu_get_libc_version = libc.gnu_get_libc_version  # glibc only (musl has no arenas)
    except (OSError, AttributeError):
        return False
    del gnu_get_libc_version
    mallopt.argtypes = [ctypes.c_int, ctypes.c_int]
    mallopt.restype = ctypes.c_int
    ok = all(
        mallopt(param, value)
        for param, value in (
            (_M_ARENA_MAX, ARENA_MAX),
            (_M_MMAP_THRESHOLD, MMAP_THRESHOLD_BYTES),
            (_M_TRIM_THRESHOLD, TRIM_THRESHOLD_BYTES),
        )
    )
    _done = ok
    return ok
