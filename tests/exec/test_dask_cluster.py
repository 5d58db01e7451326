"""Issue 15: the Dask engine on a real cluster, a ``dask scheduler`` and two ``dask worker``
processes (``--nthreads 1``) on 127.0.0.1 with random ports, not a LocalCluster.

What it checks, each a bug seen on such a cluster before:
- bad input (InputError) runs once, not three times (other failures are still retried);
- losing every worker fails in bounded time with one line, the store untouched;
- no scheduler at the address, or the scheduler killed mid-run: one line naming its address;
- workers started without any storage environment get the client's with every unit, so they
  write to the client's S3 endpoint (a moto server on loopback), not to the public cloud.
And what already worked stays so: a killed worker is survived, results are byte-identical.
"""

from __future__ import annotations

import contextlib
import hashlib
import json
import os
import re
import signal
import socket
import subprocess
import sys
import threading
import time
import uuid
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import Any

import numpy as np
import pytest

import dancedata
from dancedata.errors import InputError
from dancedata.exec.storage_env import STORAGE_ENV_PREFIXES
from dancedata.exec.threads import thread_env
from dancedata.store.fs import STORAGE_OPTIONS_ENV
from dancedata.store.validate import validate_store
from tests.helpers import REPO, importorskip_unless_ci, own_numba_cache, run_cli
from tests.s3_server import moto_s3

importorskip_unless_ci("distributed")

from dancedata.exec.executors import (  # noqa: E402
    NO_WORKERS_TIMEOUT_ENV,
    ClusterError,
    DaskExecutor,
)

# slow: a real Dask scheduler and worker processes
pytestmark = pytest.mark.slow

DASK = Path(sys.executable).parent / "dask"
START_TIMEOUT_S = 120.0  # two workers import dask on a shared 2-core machine
NO_WORKERS_S = 3.0


def _worker_env() -> dict[str, str]:
    """This environment without any storage variable (no endpoint, no credentials), numeric
    pools pinned to one thread, and the repository importable (tests' task functions)."""
    env = {
        name: value
        for name, value in os.environ.items()
        if name != STORAGE_OPTIONS_ENV and not name.startswith(STORAGE_ENV_PREFIXES)
    }
    env.update(thread_env(1))
    # The scheduler unpickles task graphs too, so both need this module (``test_dask_cluster``
    # under pytest's default import mode, ``tests.exec.test_dask_cluster`` otherwise).
    paths = [str(Path(__file__).parent), str(REPO), env.get("PYTHONPATH")]
    env["PYTHONPATH"] = os.pathsep.join(filter(None, paths))
    return env


class Cluster:
    """A scheduler and ``n_workers`` worker processes, each in its own process group (a worker
    is a nanny plus the worker it starts: killing the group kills both)."""

    def __init__(self, root: Path, n_workers: int) -> None:
        root.mkdir(parents=True, exist_ok=True)
        self.root = root
        self.scheduler_file = root / "scheduler.json"
        self.env = _worker_env()
        self.scheduler: subprocess.Popen | None = None
        self.workers: list[subprocess.Popen] = []
        try:
            self.scheduler = self._spawn(
                "scheduler",
                [
                    "scheduler",
                    "--host",
                    "127.0.0.1",
                    "--port",
                    "0",
                    "--no-dashboard",
                    "--scheduler-file",
                    str(self.scheduler_file),
                ],
            )
            self.address = self._wait_for_address()
            for _ in range(n_workers):
                self.add_worker()
            if n_workers:
                self.wait_for_workers(n_workers)
        except BaseException:
            self.close()
            raise

    def _spawn(self, name: str, args: list[str]) -> subprocess.Popen:
        log = open(self.root / f"{name}.log", "ab")  # noqa: SIM115 - the process owns it
        try:
            return subprocess.Popen(
                [str(DASK), *args],
                stdout=log,
                stderr=subprocess.STDOUT,
                # processes of a cluster run side by side: a numba cache folder each
                env=own_numba_cache(self.env, f"dask-{self.root.name}-{name}"),
                cwd=self.root,
                start_new_session=True,
            )
        finally:
            log.close()

    def _wait_for_address(self) -> str:
        deadline = time.monotonic() + START_TIMEOUT_S
        while time.monotonic() < deadline:
            assert self.scheduler is not None and self.scheduler.poll() is None, self.logs()
            try:
                return json.loads(self.scheduler_file.read_text())["address"]
            except (OSError, ValueError, KeyError):
                time.sleep(0.2)
        raise AssertionError(f"no scheduler address within {START_TIMEOUT_S} s\n{self.logs()}")

    def add_worker(self) -> None:
        name = f"worker-{len(self.workers)}"
        args = ["worker", "--scheduler-file", str(self.scheduler_file), "--nthreads", "1"]
        args += ["--host", "127.0.0.1", "--no-dashboard", "--name", name]
        self.workers.append(self._spawn(name, args))

    def wait_for_workers(self, n: int) -> None:
        from distributed import Client

        with Client(self.address, set_as_default=False, timeout=30) as client:
            client.wait_for_workers(n, timeout=START_TIMEOUT_S)

    def kill_worker(self, index: int) -> None:
        _kill_group(self.workers[index])

    def kill_scheduler(self) -> None:
        assert self.scheduler is not None
        _kill_group(self.scheduler)

    def logs(self) -> str:
        return "\n".join(
            f"--- {path.name}\n{path.read_text(errors='replace')[-3000:]}"
            for path in sorted(self.root.glob("*.log"))
        )

    def worker_log_text(self) -> str:
        return "".join(p.read_text(errors="replace") for p in self.root.glob("worker-*.log"))

    def close(self) -> None:
        for proc in [*self.workers, self.scheduler]:
            if proc is not None:
                _kill_group(proc)


def _kill_group(proc: subprocess.Popen) -> None:
    """SIGKILL the process and every child in its group (a lost machine, not a shutdown)."""
    with contextlib.suppress(ProcessLookupError):
        os.killpg(proc.pid, signal.SIGKILL)
    proc.wait(timeout=30)


@pytest.fixture(scope="module")
def cluster(tmp_path_factory) -> Iterator[Cluster]:
    """One cluster for the tests that leave it whole."""
    started = Cluster(tmp_path_factory.mktemp("cluster"), n_workers=2)
    try:
        yield started
    finally:
        started.close()


@pytest.fixture
def fresh_cluster(tmp_path) -> Iterator[Cluster]:
    """A cluster of its own for a test that kills parts of it."""
    started = Cluster(tmp_path / "cluster", n_workers=2)
    try:
        yield started
    finally:
        started.close()


@pytest.fixture(scope="module")
def raw(tmp_path_factory) -> Path:
    """A small synthetic AIST++ tree: 4 sequences, 3 songs."""
    root = tmp_path_factory.mktemp("raw") / "aist"
    run_cli("synth", "aist", str(root), "--sequences", "4", "-q")
    return root


def _ingest(raw: Path, store: str | Path, env: dict[str, str] | None = None) -> None:
    run_cli("ingest", "aist", str(raw), "--store", str(store), "-q", env=env)


def _bounded(call: Callable[[], Any], limit_s: float) -> tuple[Any, BaseException | None, float]:
    """Run ``call`` in a daemon thread for at most ``limit_s`` s: (result, error, seconds). A
    call still running then fails the test instead of hanging it."""
    out: dict[str, Any] = {}

    def target() -> None:
        try:
            out["result"] = call()
        except BaseException as exc:  # noqa: BLE001 - handed to the test
            out["error"] = exc

    start = time.monotonic()
    thread = threading.Thread(target=target, daemon=True)
    thread.start()
    thread.join(limit_s)
    elapsed = time.monotonic() - start
    if thread.is_alive():
        pytest.fail(f"still running after {limit_s:g} s (hangs)")
    return out.get("result"), out.get("error"), elapsed


# -- task functions (imported by the workers from this module) ---------------------------------


def _count_and_fail(item: tuple[str, str]) -> int:
    """Records the call in a directory; bad input fails every time, a transient failure the
    first two times."""
    calls, kind = item
    Path(calls, uuid.uuid4().hex).touch()
    n = len(os.listdir(calls))
    if kind == "input":
        raise InputError("truncated header", "/data/bad.bvh")
    if kind == "transient" and n <= 2:
        raise RuntimeError(f"transient failure {n}")
    return n


def _slow_square(value: int) -> int:
    time.sleep(0.5)
    return value * value


def _worker_view_of_store(url: str) -> dict[str, Any]:
    """Where this worker reaches ``url``: its endpoint, and the store's top level as seen
    from there. Without an endpoint, answers at once instead of trying the public cloud."""
    endpoint = os.environ.get("AWS_ENDPOINT_URL")
    if not endpoint:
        return {"endpoint": None}
    from dancedata.store.fs import remote_fs

    fs, path = remote_fs(url)
    fs.invalidate_cache()
    return {"endpoint": endpoint, "listing": sorted(p.rsplit("/", 1)[-1] for p in fs.ls(path))}


# -- bad input is not retried ------------------------------------------------------------------


def test_bad_input_runs_once_and_other_failures_are_retried(cluster, tmp_path):
    bad, flaky = tmp_path / "bad", tmp_path / "flaky"
    bad.mkdir()
    flaky.mkdir()
    with DaskExecutor(cluster.address) as executor:
        assert executor.describe() == {"engine": "dask", "workers": 2, "address": cluster.address}
        with pytest.raises(InputError, match=r"/data/bad\.bvh: truncated header"):
            list(executor.map_unordered(_count_and_fail, [(str(bad), "input")]))
        assert len(os.listdir(bad)) == 1  # was 3: the scheduler retried it twice
        # Anything else is retried (retries=2): two failures, then the third call succeeds.
        assert dict(executor.map_unordered(_count_and_fail, [(str(flaky), "transient")])) == {0: 3}


def test_a_failure_that_persists_fails_after_its_retries(cluster, tmp_path):
    calls = tmp_path / "calls"
    calls.mkdir()
    with (
        DaskExecutor(cluster.address, retries=1) as executor,
        pytest.raises(RuntimeError, match="transient failure 2"),
    ):
        list(executor.map_unordered(_count_and_fail, [(str(calls), "transient")]))
    assert len(os.listdir(calls)) == 2


def test_featurize_with_changed_music_is_one_line_run_once(cluster, raw, tmp_path):
    """A music file changed after ingest (same size and mtime, so only the worker's hash check
    sees it): one line naming the file, exit 1, and the unit computed once."""
    copy = tmp_path / "aist"
    subprocess.run(["cp", "-r", str(raw), str(copy)], check=True)
    store = tmp_path / "store"
    _ingest(copy, store)
    wav = sorted((copy / "wav").glob("*.wav"))[0]
    _flip_a_byte_keeping_the_stamp(wav)
    failed_before = cluster.worker_log_text().count("Compute Failed")
    # An empty feature cache: a track whose features are cached (keyed by the hash verified at
    # ingest) is never decoded, so an earlier test's run on the same synthetic music would hide
    # the change from the worker's hash check.
    proc = run_cli(
        "featurize", str(store), "-q", "--no-motion", "--audio-families", "fact",
        "--stems", "none", "--dask", cluster.address, check=False, timeout=300,
        env={"DANCEDATA_CACHE": str(tmp_path / "empty-cache")},
    )  # fmt: skip
    assert proc.returncode == 1, proc.stderr
    assert proc.stderr.splitlines() == [proc.stderr.strip()] and proc.stderr.startswith(
        f"error: {wav}: changed since ingest"
    ), proc.stderr
    assert cluster.worker_log_text().count("Compute Failed") - failed_before == 1
    assert dancedata.open_store(store).version == "v1"


def _flip_a_byte_keeping_the_stamp(path: Path) -> None:
    stat = path.stat()
    with open(path, "r+b") as handle:
        handle.seek(stat.st_size // 2)
        byte = handle.read(1)
        handle.seek(stat.st_size // 2)
        handle.write(bytes([byte[0] ^ 0xFF]))
    os.utime(path, ns=(stat.st_atime_ns, stat.st_mtime_ns))


# -- workers lost --------------------------------------------------------------------------------


def test_a_killed_worker_is_survived(fresh_cluster):
    items = list(range(8))

    def run() -> dict[int, int]:
        results = {}
        with DaskExecutor(fresh_cluster.address) as executor:
            for index, value in executor.map_unordered(_slow_square, items):
                if not results:
                    fresh_cluster.kill_worker(0)
                results[index] = value
        return results

    results, error, _ = _bounded(run, 120)
    assert error is None, error
    assert results == {i: i * i for i in items}


def test_losing_every_worker_fails_in_bounded_time(fresh_cluster, monkeypatch):
    monkeypatch.setenv(NO_WORKERS_TIMEOUT_ENV, f"{NO_WORKERS_S:g}")
    killed_at: list[float] = []

    def run() -> None:
        with DaskExecutor(fresh_cluster.address) as executor:
            for _ in executor.map_unordered(_slow_square, list(range(12))):
                if not killed_at:
                    fresh_cluster.kill_worker(0)
                    fresh_cluster.kill_worker(1)
                    killed_at.append(time.monotonic())

    _, error, _ = _bounded(run, 120)
    assert isinstance(error, ClusterError), error
    pattern = (
        rf"the Dask cluster at {re.escape(fresh_cluster.address)}: no workers left for 3 s; "
        r"\d+ of 12 tasks not done"
    )
    assert re.fullmatch(pattern, str(error)), str(error)
    # Noticed by the scheduler (closed connections), then NO_WORKERS_S, polled every second.
    assert time.monotonic() - killed_at[0] < NO_WORKERS_S + 15


def test_featurize_without_workers_fails_and_a_later_run_resumes(raw, tmp_path):
    """A scheduler with no worker: one line, exit 1, store as it was; once workers join, the
    same command writes the same bytes as a serial run."""
    serial, store = tmp_path / "serial", tmp_path / "store"
    _ingest(raw, serial)
    _ingest(raw, store)
    run_cli("featurize", str(serial), "-q", "--no-audio")
    empty = Cluster(tmp_path / "cluster", n_workers=0)
    try:
        args = ("featurize", str(store), "-q", "--no-audio", "--dask", empty.address)
        env = {NO_WORKERS_TIMEOUT_ENV: f"{NO_WORKERS_S:g}"}
        start = time.monotonic()
        proc = run_cli(*args, check=False, env=env, timeout=300)
        assert proc.returncode == 1, proc.stderr
        assert re.fullmatch(
            rf"error: the Dask cluster at {re.escape(empty.address)}: no workers for 3 s; "
            r"(\d+) of \1 tasks not done\n",
            proc.stderr,
        ), proc.stderr
        assert time.monotonic() - start < 120
        assert dancedata.open_store(store).version == "v1"
        assert validate_store(store) == []

        empty.add_worker()
        empty.add_worker()
        empty.wait_for_workers(2)
        out = json.loads(run_cli(*args, "--json", env=env, timeout=300).stdout)
        assert out["version"] == "v2"
        assert out["counts"]["engine"] == {
            "engine": "dask",
            "workers": 2,
            "address": empty.address,
        }
    finally:
        empty.close()
    assert _version_files(store, "v2") == _version_files(serial, "v2")


def _version_files(store: Path, version: str) -> dict[str, str]:
    """sha256 of every file of a version but its manifest (times, counts, engine); of
    checksums.json only its ``files``."""
    root = store / "versions" / version

    def digest(path: Path) -> str:
        data = path.read_bytes()
        if path == root / "checksums.json":
            data = json.dumps(json.loads(data)["files"], sort_keys=True).encode()
        return hashlib.sha256(data).hexdigest()

    return {
        p.relative_to(root).as_posix(): digest(p)
        for p in sorted(root.rglob("*"))
        if p.is_file() and p.name != "manifest.json"
    }


# -- the scheduler ---------------------------------------------------------------------------


def _free_port() -> int:
    with socket.socket() as sock:
        sock.bind(("127.0.0.1", 0))
        return sock.getsockname()[1]


def test_no_scheduler_is_one_line_naming_the_address(raw, tmp_path):
    store = tmp_path / "store"
    _ingest(raw, store)
    address = f"tcp://127.0.0.1:{_free_port()}"
    env = {"DASK_DISTRIBUTED__COMM__TIMEOUTS__CONNECT": "2s"}
    proc = run_cli(
        "featurize", str(store), "-q", "--no-audio", "--dask", address,
        check=False, env=env, timeout=300,
    )  # fmt: skip
    assert proc.returncode == 1
    assert proc.stderr == (
        f"error: the Dask cluster at {address}: no scheduler answers (Timed out trying to "
        f"connect to {address} after 2 s)\n"
    )
    proc = run_cli("featurize", str(store), "-q", "--dask", "foo://x", check=False)
    assert proc.returncode == 1
    assert proc.stderr.startswith(
        "error: the Dask cluster at foo://x: not a scheduler address (unknown address scheme"
    ), proc.stderr
    assert len(proc.stderr.splitlines()) == 1
    assert dancedata.open_store(store).version == "v1"


def test_scheduler_killed_mid_run_is_one_line(fresh_cluster, capfd):
    killed_at: list[float] = []

    def run() -> None:
        with DaskExecutor(fresh_cluster.address) as executor:
            for _ in executor.map_unordered(_slow_square, list(range(12))):
                if not killed_at:
                    fresh_cluster.kill_scheduler()
                    killed_at.append(time.monotonic())

    _, error, _ = _bounded(run, 120)
    assert isinstance(error, ClusterError), error
    assert re.fullmatch(
        rf"the Dask cluster at {re.escape(fresh_cluster.address)}: lost the connection to the "
        r"scheduler(; \d+ tasks not done| \(.*\))",
        str(error),
    ), str(error)
    assert time.monotonic() - killed_at[0] < 30
    assert "Traceback" not in capfd.readouterr().err  # Dask's reconnect log stays quiet


# -- storage options travel with the units -----------------------------------------------------


@pytest.fixture(scope="module")
def s3(tmp_path_factory):
    """A moto S3 server on loopback with bucket ``dance``, and the client-side environment
    that reaches it (the workers have none of it)."""
    importorskip_unless_ci("moto.server")
    importorskip_unless_ci("s3fs")
    with moto_s3("dance") as env:
        yield env


def test_workers_reach_the_store_through_the_clients_endpoint(cluster, s3, raw):
    url = "s3://dance/stores/probe"
    _ingest(raw, url, env=s3)
    with DaskExecutor(cluster.address) as executor:
        views = dict(executor.map_unordered(_worker_view_of_store, [url] * 4))
    for view in views.values():
        assert view["endpoint"] == s3["AWS_ENDPOINT_URL"], view  # was None: the public cloud
        assert "store.json" in view["listing"] and "versions" in view["listing"], view


def test_featurize_on_s3_with_workers_without_storage_env(cluster, s3, raw, tmp_path):
    url, local = "s3://dance/stores/featurized", tmp_path / "local"
    _ingest(raw, url, env=s3)
    _ingest(raw, local)
    run_cli("featurize", str(local), "-q", "--no-audio")
    run_cli("featurize", url, "-q", "--no-audio", "--dask", cluster.address, env=s3, timeout=300)
    remote, here = dancedata.open_store(url), dancedata.open_store(local)
    assert remote.version == "v2"
    assert remote.array_names() == here.array_names()
    for name in here.array_names():
        assert np.array_equal(remote.zarr(name)[...], here.zarr(name)[...], equal_nan=True), name
