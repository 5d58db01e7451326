"""Progress of long steps on stderr, silenced by ``--quiet``.

In a terminal: tqdm bars. When stderr is not a terminal (a log file, a pipe, CI), bars would
write carriage returns and cursor escape codes into the log; there each step writes plain
lines instead, ``<desc>: <n>/<total> <unit> (<pct>%, <seconds> s)``, at most one every
:data:`PLAIN_INTERVAL_S` seconds (``$DANCEDATA_PROGRESS_SECONDS`` overrides it; 0 writes one
per update) and always one when the step ends.
"""

from __future__ import annotations

import os
import sys
import time
from collections.abc import Iterable, Iterator
from typing import Any, TextIO, TypeVar

T = TypeVar("T")
_QUIET = False
PLAIN_INTERVAL_S = 10.0


def set_quiet(quiet: bool) -> None:
    global _QUIET
    _QUIET = quiet


def note(text: str) -> None:
    """One line on stderr (a result worth seeing, e.g. an estimated tempo), unless quiet."""
    if not _QUIET:
        print(text, file=sys.stderr, flush=True)


def _plain_interval() -> float:
    text = os.environ.get("DANCEDATA_PROGRESS_SECONDS")
    try:
        return max(0.0, float(text)) if text else PLAIN_INTERVAL_S
    except ValueError:
        return PLAIN_INTERVAL_S


def _stderr_is_terminal() -> bool:
    try:
        return sys.stderr.isatty()
    except (AttributeError, ValueError):  # replaced or closed stream
        return False


class PlainProgress:
    """Progress as plain lines (no ``\\r``, no escape codes), for logs; see the module doc.

    Same use as a tqdm bar: :meth:`update` then :meth:`close`.
    """

    def __init__(
        self,
        desc: str,
        total: int | None,
        unit: str = "it",
        interval_s: float | None = None,
        stream: TextIO | None = None,
    ) -> None:
        self.desc = desc
        self.total = total
        self.unit = unit
        self.n = 0
        self.interval_s = _plain_interval() if interval_s is None else interval_s
        self.stream = stream
        self.started = time.monotonic()
        self._last_line = self.started
        self._closed = False

    def line(self) -> str:
        """The current state as one line."""
        elapsed = time.monotonic() - self.started
        if self.total:
            share = f"{100.0 * self.n / self.total:.0f}%, "
            return f"{self.desc}: {self.n}/{self.total} {self.unit} ({share}{elapsed:.1f} s)"
        return f"{self.desc}: {self.n} {self.unit} ({elapsed:.1f} s)"

    def _write(self) -> None:
        stream = self.stream if self.stream is not None else sys.stderr
        print(self.line(), file=stream, flush=True)
        self._last_line = time.monotonic()

    def update(self, n: int = 1) -> None:
        self.n += n
        if self._closed or not n:
            return
        finished = self.total is not None and self.n >= self.total
        if not finished and time.monotonic() - self._last_line >= self.interval_s:
            self._write()

    def close(self) -> None:
        """Write the final line, unless an exception is on its way (the error is the last
        line a user reads, not a progress line after it)."""
        if not self._closed:
            self._closed = True
            if sys.exc_info()[0] is None:
                self._write()


class _Silent:
    """What ``--quiet`` gets: a bar that writes nothing."""

    n = 0

    def update(self, n: int = 1) -> None:
        self.n += n

    def close(self) -> None:
        pass


def restart_clock(bar: Any, seconds_ago: float) -> None:
    """Count ``bar``'s time from ``seconds_ago`` seconds before now: a step whose bar was
    made with others up front (all jobs submitted at once) times itself from when its first
    task started, not from the start of the command."""
    ago = max(0.0, float(seconds_ago or 0.0))
    if isinstance(bar, PlainProgress):
        bar.started = time.monotonic() - ago
    elif hasattr(bar, "start_t"):  # tqdm, whose clock is its own timer (default time.time)
        bar.start_t = bar._time() - ago  # noqa: SLF001 - tqdm's documented clock


def progress(
    items: Iterable[T], desc: str, total: int | None = None, unit: str = "it"
) -> Iterator[T]:
    """Iterate ``items``, reporting progress as ``desc`` unless quiet."""
    if total is None and hasattr(items, "__len__"):
        total = len(items)  # type: ignore[arg-type]
    bar = progress_bar(desc, total, unit)
    try:
        for item in items:
            yield item
            bar.update(1)
    finally:
        bar.close()


def progress_bar(desc: str, total: int | None, unit: str = "it") -> Any:
    """A bar to advance by hand (``bar.update(n)``, ``bar.close()``): tqdm in a terminal,
    :class:`PlainProgress` lines otherwise, silent when quiet."""
    if _QUIET:
        return _Silent()
    if not _stderr_is_terminal():
        return PlainProgress(desc, total, unit)
    from tqdm import tqdm

    return tqdm(desc=desc, total=total, unit=unit, leave=False, dynamic_ncols=True)
