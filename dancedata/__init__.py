"""dancedata: raw music-and-dance data in, versioned analysis-ready stores out.

Importing this package is cheap: zarr, librosa and friends load only when a function needs them,
so that ``dancedata --help`` starts fast.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

from dancedata._version import __version__

if TYPE_CHECKING:
    from dancedata.read.loader import DanceStore

__all__ = ["__version__", "open_store"]


def open_store(path: str, version: str | None = None) -> DanceStore:
    """Open a store for reading; ``version`` defaults to the latest committed one."""
    from dancedata.read.loader import open_store as _open_store

    return _open_store(path, version=version)
