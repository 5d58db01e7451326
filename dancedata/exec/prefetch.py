"""Run a producer one step ahead of its consumer, in a thread of this process.

For pipelines whose two halves spend their time in native code that releases the GIL (OpenCV
drawing and colour conversion on one side, the H.264 encoder on the other): the consumer
works on item k while the producer makes item k + 1, so two cores are both busy. Items arrive
in the producer's order; an exception in the producer is raised in the consumer, at the place
the failing item would have arrived. Memory is bounded by ``depth`` items in flight.
"""

from __future__ import annotations

import queue
import threading
from collections.abc import Iterable, Iterator
from typing import TypeVar

T = TypeVar("T")

_DONE = object()


class _Failed:
    def __init__(self, error: BaseException) -> None:
        self.error = error


def prefetched(items: Iterable[T], *, depth: int = 4) -> Iterator[T]:
    """The items of ``items``, produced in a background thread at most ``depth`` ahead.

    Leaving the loop early (break, an exception, Ctrl-C in the consumer) stops the producer
    at its next item; it is a daemon thread, so it never keeps the process alive."""
    if depth < 1:
        raise ValueError("depth must be at least 1")
    handoff: queue.Queue = queue.Queue(maxsize=depth)
    stop = threading.Event()

    def put(value: object) -> bool:
        while not stop.is_set():
            try:
                handoff.put(value, timeout=0.1)
                return True
            except queue.Full:
                continue
        return False

    def produce() -> None:
        try:
            for item in items:
                if not put(item):
                    return
        except BaseException as exc:  # noqa: BLE001 - handed to the consumer, raised there
            put(_Failed(exc))
            return
        put(_DONE)

    worker = threading.Thread(target=produce, name="dancedata-prefetch", daemon=True)
    worker.start()
    try:
        while True:
            value = handoff.get()
            if value is _DONE:
                return
            if isinstance(value, _Failed):
                raise value.error
            yield value  # type: ignore[misc]
    finally:
        stop.set()
        worker.join(timeout=5.0)
