"""The store conformance suite (as zarr-python's store tests): ONE set of store behaviours, run on
every backend through the public API and the CLI, so that integrity, locks, URLs and failures
behave the same on a local directory and on object storage (issue 15, item 1).

Backends: ``local`` (a directory under pytest's tmp_path) and ``s3`` (a bucket on a real
S3-compatible server, moto in server mode, on 127.0.0.1; see tests/s3_server.py). Each builds the
same store from the same synthetic AIST++ set with the CLI (v1 ingest, v2 featurize motion only,
v3 segment) and every test runs once per backend; a test that damages a store works on its own
copy. Behaviours: versions and latest, identical arrays and tables on both backends, ``validate``
and ``validate --deep`` (a store as committed is valid; a chunk whose bytes are zeroed, a chunk
rewritten through zarr and a changed table byte are each caught by ``--deep``),
``info``, the writer lock (held, refused, stale lock taken over, ``dancedata unlock``),
``checkout``, and failures (a missing store; on S3 a dead endpoint and missing credentials are
one line naming the endpoint, exit 1).
"""

from __future__ import annotations

import io
import json
import os
import shutil
import socket
import subprocess
import sys
from collections.abc import Iterator
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import pyarrow.parquet as pq
import pytest

import dancedata
from dancedata.store.layout import StoreLayout
from dancedata.store.lock import LOCK_FILE, this_holder
from dancedata.store.writer import hold_store_lock
from dancedata.synth.aist import synth_aist
from tests.helpers import run_cli
from tests.s3_server import closed_port, moto_s3

BACKENDS = ("local", "s3")
BUCKET = "conformance"
# First chunk of an array v1 (ingest) writes and every later version carries over: by hard link
# locally, by reference on object stores (see store.references), so it is damaged where v1
# stores it.
CHUNK = "data.zarr/motion/axis_angle/c/0/0/0"
CHUNK_NAME = "array motion/axis_angle chunk (0, 0, 0)"


@dataclass
class Site:
    """Where one backend's stores live, and raw file access to them that does not go through
    dancedata (so damage is done, and seen, independently of the code under test)."""

    kind: str
    root: str  # a local folder, or s3://bucket
    fs: Any = None  # s3fs filesystem for the s3 site
    made: list[str] = field(default_factory=list)

    def url(self, name: str) -> str:
        return f"{self.root}/{name}" if self.kind == "s3" else str(Path(self.root) / name)

    def _key(self, store: str, rel: str) -> str:
        return f"{store.removeprefix('s3://')}/{rel}"

    def read(self, store: str, rel: str) -> bytes:
        if self.kind == "s3":
            self.fs.invalidate_cache()
            return self.fs.cat_file(self._key(store, rel))
        return (Path(store) / rel).read_bytes()

    def write(self, store: str, rel: str, data: bytes) -> None:
        if self.kind == "s3":
            self.fs.pipe_file(self._key(store, rel), data)
            self.fs.invalidate_cache()
        else:
            path = Path(store) / rel
            path.unlink(missing_ok=True)  # a hard link may share the file: break it
            path.write_bytes(data)

    def exists(self, store: str, rel: str) -> bool:
        if self.kind == "s3":
            self.fs.invalidate_cache()
            return bool(self.fs.exists(self._key(store, rel)))
        return (Path(store) / rel).exists()

    def copy(self, store: str, name: str) -> str:
        """A copy of ``store`` at a new name (the original stays pristine for other tests)."""
        target = self.url(name)
        if self.kind == "s3":
            self.fs.copy(store.removeprefix("s3://"), target.removeprefix("s3://"), recursive=True)
            self.fs.invalidate_cache()
        else:
            shutil.copytree(store, target, symlinks=True)
        return target


@pytest.fixture(scope="module")
def raw(tmp_path_factory) -> Path:
    path = tmp_path_factory.mktemp("conformance") / "raw"
    synth_aist(path, n_sequences=2, seed=3)
    return path


@pytest.fixture(scope="module")
def s3_site() -> Iterator[Site]:
    s3fs = pytest.importorskip("s3fs")
    with moto_s3(BUCKET):
        yield Site("s3", f"s3://{BUCKET}", fs=s3fs.S3FileSystem())


@pytest.fixture(scope="module")
def local_site(tmp_path_factory) -> Site:
    return Site("local", str(tmp_path_factory.mktemp("conformance-local")))


def _build(site: Site, raw: Path) -> str:
    """v1 ingest, v2 featurize (motion: audio features are covered by test_remote), v3 segment,
    all through the CLI."""
    url = site.url("store")
    run_cli("ingest", "aist", str(raw), "--store", url, "-q")
    run_cli("featurize", url, "-q", "--no-audio")
    run_cli("segment", url, "-q")
    return url


@pytest.fixture(scope="module")
def built(local_site, s3_site, raw) -> dict[str, tuple[Site, str]]:
    """Both backends, each with the same store (built once for the module)."""
    return {site.kind: (site, _build(site, raw)) for site in (local_site, s3_site)}


@pytest.fixture(params=BACKENDS)
def backend(request, built) -> tuple[Site, str]:
    """(site, store URL) of one backend: every test taking it runs on each."""
    return built[request.param]


def _one_line_error(proc: subprocess.CompletedProcess) -> str:
    """The single stderr line of a failed command (asserted to be one line, exit 1)."""
    lines = proc.stderr.strip().splitlines()
    assert proc.returncode == 1, proc.stderr
    assert len(lines) == 1, proc.stderr
    return lines[0]


# -- versions and data -------------------------------------------------------------------------
@pytest.mark.slow
def test_versions_and_latest(backend):
    _site, url = backend
    rows = json.loads(run_cli("versions", url, "--json").stdout)
    assert [r["version"] for r in rows] == ["v1", "v2", "v3"]
    assert [r["version"] for r in rows if r["latest"]] == ["v3"]
    assert [r["parent"] for r in rows] == [None, "v1", "v2"]
    layout = StoreLayout(url)
    assert layout.committed_versions() == ["v1", "v2", "v3"] and layout.latest() == "v3"
    assert dancedata.open_store(url).version == "v3"
    assert dancedata.open_store(url, "v1").version == "v1"


@pytest.mark.slow
def test_both_backends_hold_the_same_arrays_and_tables(built):
    (_, local_url), (_, s3_url) = built["local"], built["s3"]
    for version in ("v1", "v2", "v3"):
        local, remote = (
            dancedata.open_store(local_url, version),
            dancedata.open_store(s3_url, version),
        )
        assert remote.array_names() == local.array_names() and local.array_names()
        for name in local.array_names():
            a, b = local.zarr(name), remote.zarr(name)
            assert a.dtype == b.dtype and a.shape == b.shape, name
            assert np.array_equal(a[...], b[...], equal_nan=True), (version, name)
    local, remote = dancedata.open_store(local_url), dancedata.open_store(s3_url)
    for table in ("sequences", "music", "measures", "splits"):
        assert remote.table(table).equals(local.table(table)), table
    # the manifests record the same work
    for version in ("v1", "v2", "v3"):
        a = StoreLayout(local_url).read_manifest(version)
        b = StoreLayout(s3_url).read_manifest(version)
        for manifest in (a, b):
            manifest["counts"].pop("unit_timing", None)  # seconds: differ from run to run
        assert (a["fingerprint"], a["command"], a["counts"]) == (
            b["fingerprint"],
            b["command"],
            b["counts"],
        )


# -- validate ----------------------------------------------------------------------------------
@pytest.mark.slow
def test_a_store_as_committed_is_valid_and_deep_valid(backend):
    _site, url = backend
    assert run_cli("validate", url).stdout.strip() == f"valid: {url}"
    proc = run_cli("validate", url, "--deep", check=False)
    assert proc.returncode == 0, proc.stderr  # every version has its checksums and they match
    assert proc.stdout.strip() == f"valid (deep): {url}"


@pytest.mark.slow
def test_deep_validate_catches_a_zeroed_chunk(backend, request):
    site, url = backend
    work = site.copy(url, f"zeroed-{request.node.callspec.id}")
    size = len(site.read(work, f"versions/v1/{CHUNK}"))
    site.write(work, f"versions/v1/{CHUNK}", bytes(size))
    proc = run_cli("validate", work, "--deep", check=False)
    assert proc.returncode == 1 and "valid (deep)" not in proc.stdout
    assert f"invalid: v1: {CHUNK_NAME} ({CHUNK}): sha256 differs" in proc.stderr


@pytest.mark.slow
def test_validate_catches_a_chunk_rewritten_through_zarr(backend, request):
    """Values shifted by 1 rad through zarr: a well-formed chunk (its crc32c matches, every
    value is finite, the reader serves it), so only the record made at commit can tell: its
    size, and with --deep its sha256."""
    import zarr

    site, url = backend
    work = site.copy(url, f"rewritten-{request.node.callspec.id}")
    before = site.read(work, f"versions/v1/{CHUNK}")
    array = zarr.open_array(f"{work}/versions/v1/data.zarr/motion/axis_angle", mode="r+")
    rows = array.chunks[0]
    shifted = array[:rows] + 1.0
    array[:rows] = shifted
    assert site.read(work, f"versions/v1/{CHUNK}") != before
    served = dancedata.open_store(work, "v1").zarr("motion/axis_angle")[:rows]
    assert np.array_equal(served, shifted)  # nothing but the record can see it
    for deep in ([], ["--deep"]):
        proc = run_cli("validate", work, *deep, check=False)
        assert proc.returncode == 1 and "valid" not in proc.stdout
        line = f"invalid: v1: {CHUNK_NAME} ({CHUNK}): "
        assert line in proc.stderr and "recorded at commit" in proc.stderr, proc.stderr


def _flip_a_byte_that_still_parses(data: bytes) -> bytes:
    """``data`` (a Parquet file) with one bit changed such that it still reads as a table whose
    values differ only in the ``path`` column: damage no contract check can see."""
    original = pq.read_table(io.BytesIO(data)).to_pylist()
    for offset in range(4, len(data) - 8):
        damaged = bytearray(data)
        damaged[offset] ^= 0x01
        try:
            rows = pq.read_table(io.BytesIO(bytes(damaged))).to_pylist()
        except Exception:  # noqa: BLE001 - most flips make pyarrow refuse the file
            continue
        changed = {
            k for new, old in zip(rows, original, strict=True) for k in new if new[k] != old[k]
        }
        if changed == {"path"}:
            return bytes(damaged)
    raise AssertionError("no single-bit change of the table keeps it readable")


@pytest.mark.slow
def test_deep_validate_catches_a_changed_table_byte(backend, request):
    site, url = backend
    work = site.copy(url, f"table-{request.node.callspec.id}")
    rel = "versions/v1/sequences.parquet"
    site.write(work, rel, _flip_a_byte_that_still_parses(site.read(work, rel)))
    proc = run_cli("validate", work, "--deep", check=False)
    assert proc.returncode == 1 and "valid (deep)" not in proc.stdout
    assert "invalid: v1: table sequences (sequences.parquet): sha256 differs" in proc.stderr


# -- info --------------------------------------------------------------------------------------
@pytest.mark.slow
def test_info_names_the_store_as_given(backend):
    _site, url = backend
    out = run_cli("info", url).stdout
    assert out.splitlines()[0] == f"store     {url}"
    info = json.loads(run_cli("info", url, "--json").stdout)
    assert info["store"] == url and info["version"] == "v3" and info["sequences"] == 2
    assert info["versions"] == ["v1", "v2", "v3"]
    # the end of the chain of integrity records, on every backend
    record = info["checksums_sha256"]
    assert isinstance(record, str) and len(record) == 64, record
    assert f"record    checksums.json sha256 {record}" in out


# -- the writer lock ---------------------------------------------------------------------------
def _dead_pid() -> int:
    """The pid of a process of this host that has exited."""
    proc = subprocess.Popen([sys.executable, "-c", "pass"])
    proc.wait()
    return proc.pid


def _lock_record(**changes: Any) -> bytes:
    record = {**this_holder("test holder"), **changes}
    return json.dumps(record).encode()


@pytest.mark.slow
def test_a_held_lock_refuses_a_second_writer_with_one_line(backend, request):
    site, url = backend
    work = site.copy(url, f"held-{request.node.callspec.id}")
    with hold_store_lock(work):
        assert site.exists(work, LOCK_FILE)
        proc = run_cli("segment", work, "-q", "--beats-per-measure", "2", check=False)
    line = _one_line_error(proc)
    assert line.startswith(f"error: {work}") and "locked by another writer" in line
    assert "--wait" in line
    assert not site.exists(work, LOCK_FILE)  # released
    assert StoreLayout(work).latest() == "v3"


@pytest.mark.slow
def test_a_stale_lock_is_taken_over_by_the_next_writer(backend, request):
    site, url = backend
    work = site.copy(url, f"stale-{request.node.callspec.id}")
    pid = _dead_pid()
    site.write(work, LOCK_FILE, _lock_record(pid=pid, start_ticks=None))
    proc = run_cli("segment", work, "-q", "--beats-per-measure", "2")
    assert "took over a stale store lock" in proc.stderr and f"pid {pid}" in proc.stderr
    assert StoreLayout(work).latest() == "v4"
    assert not site.exists(work, LOCK_FILE)


@pytest.mark.slow
def test_unlock_clears_a_stale_lock_and_names_the_store_as_given(backend, request):
    site, url = backend
    work = site.copy(url, f"unlock-{request.node.callspec.id}")
    assert run_cli("unlock", work).stdout.strip() == f"{work} is not locked"
    pid = _dead_pid()
    site.write(work, LOCK_FILE, _lock_record(pid=pid, start_ticks=None))
    out = run_cli("unlock", work).stdout.strip()
    assert out.startswith(f"removed the lock of pid {pid} ") and "no longer exists" in out
    assert not site.exists(work, LOCK_FILE)
    assert run_cli("unlock", work).stdout.strip() == f"{work} is not locked"


@pytest.mark.slow
def test_unlock_refuses_a_live_or_foreign_lock_unless_forced(backend, request):
    site, url = backend
    work = site.copy(url, f"foreign-{request.node.callspec.id}")
    site.write(work, LOCK_FILE, _lock_record())  # this very process: alive
    line = _one_line_error(run_cli("unlock", work, "--force", check=False))
    assert "held by a running writer" in line and site.exists(work, LOCK_FILE)
    other = f"not-{socket.gethostname()}"
    site.write(work, LOCK_FILE, _lock_record(host=other))
    line = _one_line_error(run_cli("unlock", work, check=False))
    assert "another host" in line and "--force" in line and site.exists(work, LOCK_FILE)
    # a writer never takes a foreign lock over either
    line = _one_line_error(run_cli("segment", work, "-q", "--beats-per-measure", "2", check=False))
    assert "locked by another writer" in line
    out = run_cli("unlock", work, "--force").stdout.strip()
    assert out.startswith("removed the lock of pid") and other in out
    assert not site.exists(work, LOCK_FILE)


# -- checkout ----------------------------------------------------------------------------------
@pytest.mark.slow
def test_checkout_moves_latest_and_the_next_writer_derives_from_it(backend, request):
    site, url = backend
    work = site.copy(url, f"checkout-{request.node.callspec.id}")
    assert run_cli("checkout", work, "v2").stdout.startswith("checkout: latest is now v2 (was v3)")
    layout = StoreLayout(work)
    assert layout.latest() == "v2" and layout.committed_versions() == ["v1", "v2", "v3"]
    assert dancedata.open_store(work).version == "v2"
    assert json.loads(run_cli("info", work, "--json").stdout)["version"] == "v2"
    run_cli("segment", work, "-q", "--beats-per-measure", "2")
    assert layout.latest() == "v4" and layout.read_manifest("v4")["parent"] == "v2"
    assert run_cli("validate", work).returncode == 0


# -- failures ----------------------------------------------------------------------------------
@pytest.mark.slow
def test_a_missing_store_is_one_line(backend):
    site, _url = backend
    missing = site.url("no-such-store")
    for command in (["info", missing], ["validate", missing], ["featurize", missing, "-q"]):
        line = _one_line_error(run_cli(*command, check=False))
        assert line.split(": ", 1)[0] in ("error", "invalid"), line
        assert f" {missing}: not a dancedata store" in line, line


@pytest.fixture
def dead_endpoint(built) -> dict[str, str]:
    """The S3 environment with the endpoint moved to a loopback port nothing listens on."""
    return {"AWS_ENDPOINT_URL": f"http://127.0.0.1:{closed_port()}"}


@pytest.mark.slow
def test_a_dead_endpoint_is_one_line_naming_it(built, raw, dead_endpoint):
    _site, url = built["s3"]
    endpoint = dead_endpoint["AWS_ENDPOINT_URL"]
    commands = (
        ["info", url],
        ["validate", url],
        ["featurize", url, "-q", "--no-audio"],
        ["ingest", "aist", str(raw), "--store", f"s3://{BUCKET}/new", "-q"],
    )
    for command in commands:
        proc = run_cli(*command, env=dead_endpoint, check=False)
        line = _one_line_error(proc)
        assert line == f"error: cannot reach S3 endpoint {endpoint}: connection refused", (
            command,
            line,
        )


@pytest.mark.slow
def test_missing_credentials_are_one_line_naming_the_endpoint(built, raw, tmp_path):
    _site, url = built["s3"]
    env = {
        key: value
        for key, value in os.environ.items()
        if key not in ("AWS_ACCESS_KEY_ID", "AWS_SECRET_ACCESS_KEY", "AWS_PROFILE")
    }
    env.update(
        {
            "AWS_SHARED_CREDENTIALS_FILE": str(tmp_path / "none"),
            "AWS_CONFIG_FILE": str(tmp_path / "none"),
            "AWS_EC2_METADATA_DISABLED": "true",
        }
    )
    endpoint = os.environ["AWS_ENDPOINT_URL"]
    commands = (
        ["info", url],
        ["validate", url],
        ["featurize", url, "-q", "--no-audio"],
        ["ingest", "aist", str(raw), "--store", f"s3://{BUCKET}/new", "-q"],
    )
    for command in commands:
        proc = subprocess.run(
            [sys.executable, "-m", "dancedata.cli", *command],
            capture_output=True,
            text=True,
            env=env,
            timeout=300,
        )
        line = _one_line_error(proc)
        assert line.startswith(f"error: no S3 credentials found for endpoint {endpoint}"), (
            command,
            line,
        )
