"""Progress bars for long steps (tqdm on stderr), silenced by ``--quiet``."""

from __future__ import annotations

from collections.abc import Iterable, Iterator
from typing import Any, TypeVar

T = TypeVar("T")
_QUIET = False


def set_quiet(quiet: bool) -> None:
    global _QUIET
    _QUIET = quiet


def progress(
    items: Iterable[T], desc: str, total: int | None = None, unit: str = "it"
) -> Iterator[T]:
    """Iterate ``items`` with a tqdm bar named ``desc`` unless quiet."""
    from tqdm import tqdm

    yield from tqdm(
        items, desc=desc, total=total, unit=unit, disable=_QUIET, leave=False, dynamic_ncols=True
    )


def progress_bar(desc: str, total: int, unit: str = "it") -> Any:
    """A tqdm bar to advance by hand (``bar.update(n)``, ``bar.close()``); silent when quiet."""
    from tqdm import tqdm

    return tqdm(desc=desc, total=total, unit=unit, disable=_QUIET, leave=False, dynamic_ncols=True)
