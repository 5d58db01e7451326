"""Map a function over work units on one of three engines, yielding results as units finish.

- :class:`SerialExecutor` runs in this process (``--workers 1``, the default).
- :class:`ProcessExecutor` runs a local pool of spawned processes (``--workers N``); each worker
  pins its numeric thread pools to one thread and stays alive for many units, so import and
  numba compile costs are paid once per worker, not once per unit.
- :class:`DaskExecutor` runs on a Dask distributed cluster (``--dask tcp://host:8786``) or on a
  local one it starts (``--dask local:N``: N worker processes, one thread each).

Functions and units must be picklable (top-level functions, plain data). Units are independent:
they may run in any order and any number of times (a retried unit redoes its whole work).
A :class:`~dancedata.errors.DancedataError` (bad input) is never retried; other failures are
retried up to ``retries`` times before the run fails.
"""

from __future__ import annotations

import os
from collections.abc import Callable, Iterator, Sequence
from typing import Any

from dancedata.errors import DancedataError
from dancedata.exec.threads import pin_threads, single_threaded, thread_env

DEFAULT_RETRIES = 2


def _call(fn: Callable[[Any], Any], item: Any) -> Any:
    """Run one unit in a worker, with its thread pools pinned (idempotent)."""
    pin_threads(1)
    return fn(item)


def _quit_quietly(signum: int, frame: object) -> None:
    os._exit(128 + signum)


def _init_worker(warmups: Sequence[Callable[[], None]]) -> None:
    # Ctrl-C reaches every process of the terminal's group: a worker leaves at once without a
    # traceback (its unit is not marked done, so a resumed run redoes it); the parent reports.
    import signal

    signal.signal(signal.SIGINT, _quit_quietly)
    pin_threads(1)
    for warmup in warmups:
        warmup()


class Executor:
    """Base class: :meth:`map_unordered` and :meth:`close`; usable as a context manager."""

    name = "serial"
    workers = 1

    def map_unordered(
        self, fn: Callable[[Any], Any], items: Sequence[Any]
    ) -> Iterator[tuple[int, Any]]:
        """Yield ``(index, fn(items[index]))`` for every item, in order of completion."""
        raise NotImplementedError

    def close(self) -> None:
        pass

    def __enter__(self) -> Executor:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    def describe(self) -> dict[str, Any]:
        return {"engine": self.name, "workers": self.workers}


class SerialExecutor(Executor):
    """Every unit in this process, in order."""

    def map_unordered(
        self, fn: Callable[[Any], Any], items: Sequence[Any]
    ) -> Iterator[tuple[int, Any]]:
        for index, item in enumerate(items):
            with single_threaded():
                result = fn(item)
            yield index, result


class ProcessExecutor(Executor):
    """A pool of ``workers`` spawned processes (spawn, not fork: the parent may run zarr's
    event-loop thread, which a forked child would inherit dead). ``warmups`` run once in each
    worker when it starts (e.g. compiling librosa's numba kernels)."""

    name = "processes"

    def __init__(
        self,
        workers: int,
        *,
        retries: int = DEFAULT_RETRIES,
        warmups: Sequence[Callable[[], None]] = (),
    ) -> None:
        if workers < 1:
            raise ValueError("workers must be at least 1")
        self.workers = workers
        self.retries = retries
        self.warmups = tuple(warmups)
        self._pool: Any = None

    def _ensure_pool(self) -> Any:
        if self._pool is None:
            import multiprocessing
            from concurrent.futures import ProcessPoolExecutor

            # Children read the thread limits from the environment before importing numpy.
            saved = {k: os.environ.get(k) for k in thread_env()}
            os.environ.update(thread_env(1))
            try:
                self._pool = ProcessPoolExecutor(
                    max_workers=self.workers,
                    mp_context=multiprocessing.get_context("spawn"),
                    initializer=_init_worker,
                    initargs=(self.warmups,),
                )
            finally:
                for key, value in saved.items():
                    if value is None:
                        os.environ.pop(key, None)
                    else:
                        os.environ[key] = value
        return self._pool

    def map_unordered(
        self, fn: Callable[[Any], Any], items: Sequence[Any]
    ) -> Iterator[tuple[int, Any]]:
        from concurrent.futures import FIRST_COMPLETED, wait
        from concurrent.futures.process import BrokenProcessPool

        attempts = [0] * len(items)
        pending: dict[Any, int] = {}

        def submit(index: int) -> None:
            pending[self._ensure_pool().submit(_call, fn, items[index])] = index

        for index in range(len(items)):
            submit(index)
        try:
            while pending:
                done, _ = wait(list(pending), return_when=FIRST_COMPLETED)
                for future in done:
                    if future not in pending:
                        continue  # dropped with a broken pool below
                    index = pending.pop(future)
                    try:
                        result = future.result()
                    except DancedataError:
                        raise
                    except BrokenProcessPool as exc:
                        # A dead worker (killed, out of memory) breaks the whole pool: count an
                        # attempt for every unit in flight, start a new pool, resubmit them.
                        lost = [index, *pending.values()]
                        pending.clear()
                        self._pool.shutdown(wait=False, cancel_futures=True)
                        self._pool = None
                        for lost_index in lost:
                            self._retry(lost_index, attempts, exc)
                            submit(lost_index)
                        break
                    except Exception as exc:
                        self._retry(index, attempts, exc)
                        submit(index)
                        continue
                    yield index, result
        finally:
            for future in pending:
                future.cancel()

    def _retry(self, index: int, attempts: list[int], exc: BaseException) -> None:
        attempts[index] += 1
        if attempts[index] > self.retries:
            raise exc

    def close(self) -> None:
        if self._pool is not None:
            self._pool.shutdown(wait=True, cancel_futures=True)
            self._pool = None


class DaskExecutor(Executor):
    """Units as Dask tasks. ``address`` is a scheduler address (``tcp://host:8786``) or
    ``local:N`` to start a LocalCluster of N worker processes with one thread each."""

    name = "dask"

    def __init__(self, address: str, *, retries: int = DEFAULT_RETRIES) -> None:
        try:
            from distributed import Client, LocalCluster
        except ImportError:
            raise DancedataError(
                "--dask needs the 'scale' extra: pip install 'dancedata[scale]'"
            ) from None
        self.address = address
        self.retries = retries
        self._cluster = None
        if address.startswith("local:"):
            n = int(address.split(":", 1)[1] or 1)
            self._cluster = LocalCluster(
                n_workers=n,
                threads_per_worker=1,
                processes=True,
                dashboard_address=None,
                env=thread_env(1),
            )
            self.client = Client(self._cluster)
        else:
            self.client = Client(address)
        self.client.run(pin_threads, 1)
        self.workers = len(self.client.scheduler_info().get("workers", {})) or 1

    def map_unordered(
        self, fn: Callable[[Any], Any], items: Sequence[Any]
    ) -> Iterator[tuple[int, Any]]:
        from distributed import as_completed

        futures = {
            self.client.submit(_call, fn, item, retries=self.retries, pure=False): index
            for index, item in enumerate(items)
        }
        try:
            for future in as_completed(futures):
                yield futures[future], future.result()
        finally:
            for future in futures:
                future.cancel()

    def close(self) -> None:
        self.client.close()
        if self._cluster is not None:
            self._cluster.close()

    def describe(self) -> dict[str, Any]:
        return {"engine": self.name, "workers": self.workers, "address": self.address}


def make_executor(
    workers: int = 1,
    dask: str | None = None,
    *,
    warmups: Sequence[Callable[[], None]] = (),
    retries: int = DEFAULT_RETRIES,
) -> Executor:
    """The engine the options ask for: Dask when ``dask`` is given, else a process pool when
    ``workers`` > 1, else serial."""
    if dask:
        return DaskExecutor(dask, retries=retries)
    if workers > 1:
        return ProcessExecutor(workers, retries=retries, warmups=warmups)
    return SerialExecutor()
