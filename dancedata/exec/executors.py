"""Map a function over tasks on one of three engines, yielding results as tasks finish.

- :class:`SerialExecutor` runs in this process (``--workers 1``, the default).
- :class:`ProcessExecutor` runs a local pool of spawned processes (``--workers N``); each worker
  pins its numeric thread pools to one thread and stays alive for many tasks, so import and
  numba compile costs are paid once per worker, not once per task; each worker slot has its own
  numba cache folder (:mod:`dancedata.exec.numba_cache`: workers compiling the same function
  into one cache at once can leave it crashing every later run).
- :class:`DaskExecutor` runs on a Dask distributed cluster (``--dask tcp://host:8786``) or on a
  local one it starts (``--dask local:N``: N worker processes, one thread each).

Functions and tasks must be picklable (top-level functions, plain data). Tasks are independent:
they may run in any order and any number of times (a retried task redoes its whole work).
A :class:`~dancedata.errors.DancedataError` (bad input) is never retried; other failures are
retried up to ``retries`` times before the run fails.

On Dask the retries are counted here, not by the scheduler (whose task ``retries`` would redo
bad input too); a worker that dies while running a task is handled by the scheduler (the task
moves to another worker, up to its ``allowed-failures``). A cluster that cannot run the tasks
ends the run with one line (a :class:`ClusterError`, a DancedataError naming the scheduler):
no scheduler at the address, the scheduler gone mid-run, or no worker for ``no_workers_timeout``
seconds. Remote workers get the client's storage environment with every task
(:mod:`dancedata.exec.storage_env`), so they reach the store the client means.
"""

from __future__ import annotations

import contextlib
import os
import time
from collections.abc import Callable, Iterator, Mapping, Sequence
from concurrent.futures import CancelledError
from pathlib import Path
from typing import Any

from dancedata.errors import DancedataError
from dancedata.exec.malloc import tune_malloc
from dancedata.exec.numba_cache import (
    numba_cache_base,
    seed_cache_folder,
    seed_sources,
    slot_cache_dir,
    use_dask_worker_cache,
    use_slot_cache,
)
from dancedata.exec.storage_env import apply_storage_env, storage_env
from dancedata.exec.threads import pin_threads, single_threaded, thread_env

DEFAULT_RETRIES = 2
# Seconds a Dask run waits with no worker in the cluster before it fails (all lost, none started).
DEFAULT_NO_WORKERS_TIMEOUT_S = 30.0
NO_WORKERS_TIMEOUT_ENV = "DANCEDATA_DASK_NO_WORKERS_TIMEOUT"
# Seconds between looks at the cluster while no task finishes.
_POLL_S = 1.0
# Seconds to fetch a finished task's result (small: a dict of counts) before looking again.
_FETCH_TIMEOUT_S = 5.0
_NOT_FETCHED = object()
# Seconds a starting worker waits for its numba cache slot (they are all queued before it starts).
_SLOT_TIMEOUT_S = 30.0
# Seconds closing the client may take (the scheduler may be gone).
_CLOSE_TIMEOUT_S = 10.0


class ClusterError(DancedataError):
    """The Dask cluster cannot run the tasks (no scheduler, scheduler gone, no workers): one
    line naming its address. Not bad input: the tasks finished so far are sound, so a
    resumable build may be kept for the next run (``resumable``)."""

    resumable = True


def _call(fn: Callable[[Any], Any], item: Any, env: Mapping[str, str] | None = None) -> Any:
    """Run one task in a worker, with its thread pools pinned (idempotent) and, when given,
    the client's storage environment ``env`` applied first."""
    if env:
        apply_storage_env(env)
    pin_threads(1)
    return fn(item)


def _quit_quietly(signum: int, frame: object) -> None:
    os._exit(128 + signum)


def _init_worker(
    warmups: Sequence[Callable[[], None]], slots: Any = None, numba_base: str | None = None
) -> None:
    # Ctrl-C reaches every process of the terminal's group: a worker leaves at once without a
    # traceback (its task is not marked done, so a resumed run redoes it); the parent reports.
    import queue
    import signal

    signal.signal(signal.SIGINT, _quit_quietly)
    tune_malloc()  # as the command's own process does (dancedata.exec.malloc)
    if slots is not None and numba_base is not None:
        # Before anything imports numba: a numba cache folder no other worker writes.
        # More workers than slots cannot happen in one pool; if it did, the shared cache is used.
        with contextlib.suppress(queue.Empty):
            use_slot_cache(Path(numba_base), slots.get(timeout=_SLOT_TIMEOUT_S))
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
    """Every task in this process, in order."""

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
            context = multiprocessing.get_context("spawn")
            # Each worker takes a slot number, hence a numba cache folder of its own.
            slots = context.Queue()
            base = numba_cache_base()
            for slot in range(self.workers):
                slots.put(slot)
                # A new slot starts from the functions compiled before (a copy, not a compile).
                seed_cache_folder(slot_cache_dir(base, slot), seed_sources(base))
            try:
                self._pool = ProcessPoolExecutor(
                    max_workers=self.workers,
                    mp_context=context,
                    initializer=_init_worker,
                    initargs=(self.warmups, slots, str(base)),
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
                        # attempt for every task in flight, start a new pool, resubmit them.
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
    """Tasks run on Dask. ``address`` is a scheduler address (``tcp://host:8786``) or
    ``local:N`` to start a LocalCluster of N worker processes with one thread each.

    ``connect_timeout``: seconds to reach the scheduler (default: Dask's
    ``distributed.comm.timeouts.connect``, 30 s). ``no_workers_timeout``: seconds the run waits
    while the cluster has no worker before it fails (default:
    ``$DANCEDATA_DASK_NO_WORKERS_TIMEOUT``, else 30 s). Every failure of the cluster itself is a
    one-line DancedataError naming it.
    """

    name = "dask"

    def __init__(
        self,
        address: str,
        *,
        retries: int = DEFAULT_RETRIES,
        connect_timeout: float | None = None,
        no_workers_timeout: float | None = None,
    ) -> None:
        try:
            from distributed import Client, LocalCluster
        except ImportError:
            raise DancedataError(
                "--dask needs the 'scale' extra: pip install 'dancedata[scale]'"
            ) from None
        self.address = address
        self.retries = retries
        self.no_workers_timeout = (
            _no_workers_timeout() if no_workers_timeout is None else float(no_workers_timeout)
        )
        self._cluster = None
        self._failed = False  # a ClusterError was raised: close quietly
        self.client: Any = None
        if address.startswith("local:"):
            text = address.split(":", 1)[1] or "1"
            if not text.isdigit() or int(text) < 1:
                raise DancedataError(f"--dask {address}: local:N needs a whole number N ≥ 1")
            self._cluster = LocalCluster(
                n_workers=int(text),
                threads_per_worker=1,
                processes=True,
                dashboard_address=None,
                env=thread_env(1),
            )
            self.client = Client(self._cluster)
            # The workers start together and compile librosa's gufuncs together: a numba cache
            # folder each (a shared one can be left segfaulting, numba issue 10128).
            self.client.run(use_dask_worker_cache, str(numba_cache_base()))
        else:
            self.client = self._connect(Client, address, connect_timeout)
        try:
            with self._talking():
                self.client.run(pin_threads, 1)
                n_workers = self.n_workers()
        except DancedataError:
            self.close()
            raise
        self.workers = n_workers or 1
        self.started_with_workers = n_workers > 0

    def _connect(self, client_cls: Any, address: str, timeout: float | None) -> Any:
        """A client of the scheduler at ``address``, or a one-line error naming it."""
        problem = _address_problem(address)
        if problem:
            # Checked before a Client exists: one that fails in its constructor stays alive
            # until the interpreter exits, and closing it then prints a traceback of its own.
            raise self._error(f"not a scheduler address ({problem})")
        options: dict[str, Any] = {"set_as_default": False}
        if timeout is not None:  # else Dask's distributed.comm.timeouts.connect
            options["timeout"] = timeout
        try:
            return client_cls(address, **options)
        except (OSError, TimeoutError) as exc:
            # distributed: "Timed out trying to connect to tcp://h:p after 30 s"
            raise self._error(f"no scheduler answers ({_first_line(exc)})") from None

    def _error(self, problem: str) -> ClusterError:
        self._failed = True
        return ClusterError(f"the Dask cluster at {self.address}: {problem}")

    def map_unordered(
        self, fn: Callable[[Any], Any], items: Sequence[Any]
    ) -> Iterator[tuple[int, Any]]:
        from distributed import KilledWorker

        env = storage_env()
        attempts = [0] * len(items)
        pending: dict[Any, int] = {}

        def submit(index: int) -> None:
            # No scheduler-side retries: they would redo bad input too (see below).
            with self._talking():
                future = self.client.submit(_call, fn, items[index], env, pure=False)
            pending[future] = index

        watch = _WorkerWatch(self, n_tasks=len(items))
        try:
            for index in range(len(items)):
                submit(index)
            while pending:
                done = self._wait_some(list(pending))
                if not done:
                    watch.check(len(pending))
                    continue
                for future in done:
                    index = pending.pop(future)
                    if future.status == "cancelled":
                        raise self._cancelled(len(pending) + 1)
                    if future.status == "finished":
                        value = self._fetch(future, len(pending) + 1)
                        if value is _NOT_FETCHED:
                            pending[future] = index
                            watch.check(len(pending))
                            continue
                        yield index, value
                        continue
                    if future.status == "error":
                        exc = future.exception()
                        if isinstance(exc, KilledWorker):
                            raise self._error(
                                f"a task killed {exc.allowed_failures + 1} workers in turn "
                                "(each died while running it: out of memory?); see the "
                                "workers' logs"
                            ) from None
                        if isinstance(exc, DancedataError):
                            future.result()  # bad input: never retried, raised as it is
                        attempts[index] += 1
                        if attempts[index] > self.retries:
                            future.result()
                        submit(index)
                        continue
                    pending[future] = index  # back to pending meanwhile (its data was lost)
        finally:
            if pending and self.client.status == "running":
                # Best effort, while failing already.
                with contextlib.suppress(Exception):
                    self.client.cancel(list(pending))

    def _fetch(self, future: Any, left: int) -> Any:
        """The result of a finished task, or ``_NOT_FETCHED`` when it does not arrive within
        ``_FETCH_TIMEOUT_S``: the worker holding it died meanwhile, and the scheduler computes
        it again (when it has a worker: the caller keeps watching)."""
        try:
            return future.result(timeout=_FETCH_TIMEOUT_S)
        except TimeoutError:
            return _NOT_FETCHED
        except CancelledError:
            raise self._cancelled(left) from None
        except OSError as exc:
            raise self._error(
                f"lost the connection to the scheduler ({_first_line(exc)})"
            ) from None

    @contextlib.contextmanager
    def _talking(self) -> Iterator[None]:
        """Around a call to the scheduler: a broken connection becomes one line naming it."""
        try:
            yield
        except (OSError, TimeoutError) as exc:
            raise self._error(
                f"lost the connection to the scheduler ({_first_line(exc)})"
            ) from None

    def _wait_some(self, futures: list[Any]) -> set[Any]:
        """The futures that finish (or are cancelled) within the poll interval; maybe none."""
        from distributed import wait

        with self._talking(), self.client.as_current():
            try:
                return set(wait(futures, timeout=_POLL_S, return_when="FIRST_COMPLETED").done)
            except TimeoutError:
                return set()
            except CancelledError:  # distributed raises for cancelled futures among the done
                return {f for f in futures if f.done()}

    def n_workers(self) -> int:
        """Workers in the cluster now (asks the scheduler)."""
        with self._talking():
            return len(self.client.nthreads())

    def _cancelled(self, left: int) -> ClusterError:
        if self.client.status != "running":
            return self._error(f"lost the connection to the scheduler; {left} tasks not done")
        return self._error(f"a task was cancelled on the cluster; {left} tasks not done")

    def close(self) -> None:
        if self.client is not None:
            # After a cluster failure (scheduler gone, workers gone), closing cancels the
            # client's reconnects and fetches, which Dask logs as errors with tracebacks: the run
            # has said what happened already, in one line.
            quiet = self._failed or self.client.status != "running"
            with (
                _silenced("distributed.client", "distributed.utils") if quiet else _nothing(),
                contextlib.suppress(OSError, TimeoutError),
            ):
                self.client.close(timeout=_CLOSE_TIMEOUT_S)
        if self._cluster is not None:
            self._cluster.close()

    def describe(self) -> dict[str, Any]:
        return {"engine": self.name, "workers": self.workers, "address": self.address}


class _WorkerWatch:
    """Fails a Dask run that has had no worker for ``no_workers_timeout`` seconds.

    The scheduler keeps tasks without a worker waiting forever (unless its own
    ``no-workers-timeout`` is set, which a client cannot rely on), so the client looks.
    """

    def __init__(self, executor: DaskExecutor, n_tasks: int) -> None:
        self.executor = executor
        self.n_tasks = n_tasks
        self.had_workers = executor.started_with_workers
        self.empty_since: float | None = None

    def check(self, left: int) -> None:
        """Called while no task finishes: raises once the cluster has had no worker for
        ``no_workers_timeout`` seconds."""
        now = time.monotonic()
        if self.executor.n_workers():
            self.had_workers = True
            self.empty_since = None
            return
        if self.empty_since is None:
            self.empty_since = now
        limit = self.executor.no_workers_timeout
        if now - self.empty_since >= limit:
            gone = "no workers left" if self.had_workers else "no workers"
            raise self.executor._error(
                f"{gone} for {limit:g} s; {left} of {self.n_tasks} tasks not done"
            )


def _no_workers_timeout() -> float:
    text = os.environ.get(NO_WORKERS_TIMEOUT_ENV, "").strip()
    if not text:
        return DEFAULT_NO_WORKERS_TIMEOUT_S
    try:
        value = float(text)
    except ValueError:
        value = -1.0
    if not value > 0:
        raise DancedataError(f"{NO_WORKERS_TIMEOUT_ENV}={text!r}: give seconds, a number > 0")
    return value


def _address_problem(address: str) -> str | None:
    """Why ``address`` is not a Dask scheduler address (unknown protocol, bad port), or None."""
    from distributed.comm.addressing import parse_address, parse_host_port
    from distributed.comm.registry import get_backend

    try:
        scheme, location = parse_address(address)
        get_backend(scheme)
        if scheme in ("tcp", "tls"):
            host, port = parse_host_port(location, 8786)
            if not host:
                return "no host"
            if not 0 < port < 65536:
                return f"port {port} outside 1-65535"
    except ValueError as exc:
        return _first_line(exc)
    return None


@contextlib.contextmanager
def _silenced(*names: str) -> Iterator[None]:
    """No log records from the loggers ``names`` inside the block."""
    import logging

    loggers = [logging.getLogger(name) for name in names]
    saved = [logger.disabled for logger in loggers]
    for logger in loggers:
        logger.disabled = True
    try:
        yield
    finally:
        for logger, disabled in zip(loggers, saved, strict=True):
            logger.disabled = disabled


def _nothing() -> contextlib.AbstractContextManager[None]:
    return contextlib.nullcontext()


def _first_line(exc: BaseException) -> str:
    text = str(exc).strip() or type(exc).__name__
    return text.splitlines()[0]


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
