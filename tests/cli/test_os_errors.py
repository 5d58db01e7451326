"""Storage failures are one line, not a traceback (issue 11, item 8, store side).

A full disk (ENOSPC), a file size limit (EFBIG), a read-only store (EROFS) and a store path that
is a regular file each end the command with one ``error: STORE: ...`` line naming the problem,
exit 1, the temporary version removed, the lock released and the store as it was.

The full disk and the read-only store are real: a small tmpfs, and a read-only bind mount. Both
need root (``mount``); the tests skip, saying why, where mounting is not allowed. The file-size
limit (RLIMIT_FSIZE, with SIGXFSZ ignored so that write(2) fails with EFBIG) needs no privilege
and always runs: it takes the same code path with a real OSError from the kernel.
"""

from __future__ import annotations

import os
import shutil
import subprocess
import sys
from collections.abc import Iterator
from pathlib import Path

import pytest

from dancedata.store.layout import StoreLayout
from dancedata.store.lock import LOCK_FILE
from dancedata.store.validate import validate_store
from dancedata.synth.aist import synth_aist
from tests.helpers import REPO, run_cli

# slow: ingest and featurize into full and read-only folders (subprocesses)
pytestmark = pytest.mark.slow

FEATURIZE = ("featurize", "--no-audio", "-q")  # motion only: the fastest real writer


@pytest.fixture(scope="module")
def raw(tmp_path_factory) -> Path:
    path = tmp_path_factory.mktemp("oserr") / "raw"
    synth_aist(path, n_sequences=2, seed=21)
    return path


def _mount(*args: str) -> str | None:
    """Run mount(8); None on success, else why it failed."""
    if os.geteuid() != 0:
        return "mounting needs root"
    if shutil.which("mount") is None:
        return "no mount(8) on this machine"
    proc = subprocess.run(["mount", *args], capture_output=True, text=True)
    return None if proc.returncode == 0 else f"mount {' '.join(args)}: {proc.stderr.strip()}"


def _umount(path: Path) -> None:
    if subprocess.run(["umount", str(path)], capture_output=True).returncode != 0:
        subprocess.run(["umount", "-l", str(path)], capture_output=True)


@pytest.fixture
def small_tmpfs(tmp_path: Path) -> Iterator[Path]:
    """An 8 MiB tmpfs: room for one small version, and a real ENOSPC when filled."""
    mnt = tmp_path / "tmpfs"
    mnt.mkdir()
    why = _mount("-t", "tmpfs", "-o", "size=8m", "tmpfs", str(mnt))
    if why is not None:
        pytest.skip(f"cannot make a small file system for a real ENOSPC: {why}")
    try:
        yield mnt
    finally:
        _umount(mnt)


def _fill(mount: Path, leave_kib: int) -> Path:
    """Fill ``mount`` up to ``leave_kib`` KiB free; returns the filler file."""
    stat = os.statvfs(mount)
    free_kib = stat.f_bavail * stat.f_frsize // 1024
    filler = mount / "filler"
    with open(filler, "wb") as handle:
        block = b"\0" * 1024
        for _ in range(max(0, free_kib - leave_kib)):
            handle.write(block)
    return filler


def _assert_one_line_error(proc: subprocess.CompletedProcess, store: Path, *needles: str) -> None:
    assert proc.returncode == 1, (proc.stdout, proc.stderr)
    assert "Traceback" not in proc.stderr, proc.stderr
    errors = [line for line in proc.stderr.splitlines() if line.startswith("error:")]
    assert len(errors) == 1, proc.stderr
    assert str(store) in errors[0], errors[0]
    for needle in needles:
        assert needle in errors[0], errors[0]


def _assert_untouched(store: Path, versions: list[str]) -> None:
    layout = StoreLayout(store)
    assert layout.committed_versions() == versions
    assert layout.temp_dirs() == [], "temporary version left behind"
    assert not (store / LOCK_FILE).exists(), "lock not released"
    assert not list(store.glob(f"{LOCK_FILE}.*.tmp")), "lock temporary left behind"
    assert not list(store.glob(".tmp-*")), "json temporary left behind"


def test_full_disk_during_featurize_is_one_line_and_the_store_goes_on(raw, small_tmpfs):
    store = small_tmpfs / "store"
    run_cli("ingest", "aist", str(raw), "--store", str(store), "-q")
    filler = _fill(small_tmpfs, leave_kib=200)  # less than the motion arrays need
    proc = run_cli(*FEATURIZE, str(store), check=False)
    _assert_one_line_error(proc, store, "no space left", "ENOSPC", "nothing was committed")
    _assert_untouched(store, ["v1"])
    assert validate_store(store) == []
    filler.unlink()  # space again: the next run is not wedged by the failed one
    assert "wrote version v2" in run_cli(*FEATURIZE, str(store)).stdout
    _assert_untouched(store, ["v1", "v2"])


def test_full_disk_during_the_first_ingest_leaves_no_version(raw, small_tmpfs):
    store = small_tmpfs / "store"
    _fill(small_tmpfs, leave_kib=300)  # less than one version
    proc = run_cli("ingest", "aist", str(raw), "--store", str(store), "-q", check=False)
    _assert_one_line_error(proc, store, "ENOSPC")
    _assert_untouched(store, [])


def test_file_size_limit_during_featurize_is_one_line(raw, tmp_path):
    """RLIMIT_FSIZE below the size of one motion chunk: write(2) fails with EFBIG."""
    store = tmp_path / "store"
    run_cli("ingest", "aist", str(raw), "--store", str(store), "-q")
    code = (
        "import resource, signal, sys\n"
        "signal.signal(signal.SIGXFSZ, signal.SIG_IGN)\n"
        "resource.setrlimit(resource.RLIMIT_FSIZE, (65536, 65536))\n"
        "sys.argv = ['dancedata', *sys.argv[1:]]\n"
        "from dancedata.cli.main import main\n"
        "main()\n"
    )
    proc = subprocess.run(
        [sys.executable, "-c", code, *FEATURIZE, str(store)],
        cwd=REPO,
        capture_output=True,
        text=True,
        timeout=600,
    )
    _assert_one_line_error(proc, store, "EFBIG", "nothing was committed")
    _assert_untouched(store, ["v1"])
    assert validate_store(store) == []


@pytest.fixture
def read_only_store(raw, tmp_path: Path) -> Iterator[tuple[Path, Path]]:
    """(store, read-only view of it): a bind mount remounted read-only (root bypasses chmod)."""
    store = tmp_path / "store"
    run_cli("ingest", "aist", str(raw), "--store", str(store), "-q")
    view = tmp_path / "ro"
    view.mkdir()
    why = _mount("--bind", str(store), str(view))
    if why is not None:
        pytest.skip(f"cannot make a read-only store: {why}")
    try:
        why = _mount("-o", "remount,ro,bind", str(view))
        if why is not None:
            pytest.skip(f"cannot make a read-only store: {why}")
        yield store, view
    finally:
        _umount(view)


@pytest.mark.parametrize(
    "command",
    [
        (*FEATURIZE, "{store}"),
        ("segment", "{store}", "-q"),
        ("ingest", "aist", "{other}", "--store", "{store}", "-q"),
    ],
    ids=["featurize", "segment", "ingest"],
)
def test_read_only_store_is_one_line(raw, read_only_store, command, tmp_path):
    store, view = read_only_store
    before = sorted(p.relative_to(store) for p in store.rglob("*"))
    other = tmp_path / "other"
    if "{other}" in command:
        synth_aist(other, n_sequences=2, seed=22)  # new data: ingest has something to write
    args = [a.format(store=view, other=other) for a in command]
    proc = run_cli(*args, check=False)
    _assert_one_line_error(proc, view, "read-only", "EROFS")
    assert sorted(p.relative_to(store) for p in store.rglob("*")) == before
    assert not (store / LOCK_FILE).exists()
    # reading a read-only store still works
    assert run_cli("validate", str(view)).returncode == 0


@pytest.mark.parametrize(
    "command",
    [
        ("ingest", "aist", "{raw}", "--store", "{store}", "-q"),
        (*FEATURIZE, "{store}"),
        ("segment", "{store}", "-q"),
        ("validate", "{store}"),
        ("info", "{store}"),
    ],
    ids=["ingest", "featurize", "segment", "validate", "info"],
)
def test_store_path_that_is_a_file_is_one_line(raw, tmp_path, command):
    store = tmp_path / "not-a-dir"
    store.write_bytes(b"precious\n")
    proc = run_cli(*[a.format(store=store, raw=raw) for a in command], check=False)
    assert proc.returncode == 1
    assert "Traceback" not in proc.stderr
    output = (proc.stdout + proc.stderr).strip()
    assert f"{store}: is a file, not a store directory" in output, output
    assert store.read_bytes() == b"precious\n"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["not-a-dir"]


def test_store_inside_a_file_is_one_line(raw, tmp_path):
    parent = tmp_path / "file"
    parent.write_bytes(b"x")
    store = parent / "store"
    proc = run_cli("ingest", "aist", str(raw), "--store", str(store), "-q", check=False)
    _assert_one_line_error(proc, store, "ENOTDIR")
    assert parent.read_bytes() == b"x"
