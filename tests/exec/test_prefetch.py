"""dancedata.exec.prefetch: the producer runs ahead in a thread, the consumer sees the same
items in the same order, a producer's error where its item would have been, and leaving early
stops the producer."""

from __future__ import annotations

import threading
import time

import pytest

from dancedata.exec.prefetch import prefetched


def counted(n: int, made: list[int]):  # noqa: ANN201 - a generator of ints
    """0 .. n-1, each appended to ``made`` when the producer makes it."""
    for k in range(n):
        made.append(k)
        yield k


def test_same_items_in_the_same_order_made_in_another_thread() -> None:
    made_in: set[int] = set()

    def produce():
        for k in range(1000):
            made_in.add(threading.get_ident())
            yield k

    assert list(prefetched(produce(), depth=3)) == list(range(1000))
    assert made_in and threading.get_ident() not in made_in


def test_at_most_depth_items_ahead() -> None:
    made: list[int] = []
    stream = prefetched(counted(50, made), depth=2)
    assert next(stream) == 0
    time.sleep(0.3)  # the producer fills the queue and waits
    # item 0 handed over, two queued, one more made and waiting to be put
    assert len(made) <= 1 + 2 + 1
    assert list(stream) == list(range(1, 50))


def test_a_producer_error_is_raised_where_its_item_would_be() -> None:
    def produce():
        yield 1
        yield 2
        raise ValueError("bad frame 3")

    got = []
    with pytest.raises(ValueError, match="bad frame 3"):
        for item in prefetched(produce()):
            got.append(item)
    assert got == [1, 2]


def test_leaving_early_stops_the_producer() -> None:
    made: list[int] = []
    for item in prefetched(counted(10_000, made), depth=2):
        if item == 5:
            break
    time.sleep(0.3)
    count = len(made)
    time.sleep(0.3)
    assert count == len(made) < 20
    assert not any(t.name == "dancedata-prefetch" for t in threading.enumerate())


def test_depth_must_be_positive() -> None:
    with pytest.raises(ValueError, match="depth"):
        list(prefetched([1], depth=0))
