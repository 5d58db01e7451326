"""Killing a writer part-way never corrupts a store: SIGKILL during featurize."""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import time

import pytest

from dancedata.store.layout import StoreLayout
from dancedata.store.validate import validate_store
from dancedata.synth.aist import synth_aist
from tests.helpers import run_cli

# slow: kills a featurize subprocess mid-write, then reruns it
pytestmark = pytest.mark.slow


def test_sigkill_during_featurize_keeps_previous_version_and_next_run_succeeds(tmp_path):
    raw, store = tmp_path / "raw", tmp_path / "store"
    synth_aist(raw, n_sequences=4, seed=5)
    run_cli("ingest", "aist", str(raw), "--store", str(store), "-q")
    layout = StoreLayout(store)
    v1_files = {p: p.read_bytes() for p in (store / "versions" / "v1").rglob("*") if p.is_file()}

    proc = subprocess.Popen(
        [sys.executable, "-m", "dancedata.cli", "featurize", str(store), "-q"],
        stdout=subprocess.DEVNULL,
        stderr=subprocess.DEVNULL,
        start_new_session=True,
    )
    deadline = time.monotonic() + 120
    while not layout.temp_dirs() and proc.poll() is None and time.monotonic() < deadline:
        time.sleep(0.01)
    assert proc.poll() is None, "featurize finished before it could be killed"
    time.sleep(0.5)  # well inside the version build: motion written, audio under way
    os.killpg(proc.pid, signal.SIGKILL)
    proc.wait()

    # The previous version is intact and is the only one visible.
    assert layout.committed_versions() == ["v1"]
    assert layout.read_pointer()["latest"] == "v1"
    assert validate_store(store) == []
    for path, data in v1_files.items():
        assert path.read_bytes() == data
    assert "v2" not in run_cli("versions", str(store)).stdout
    assert layout.temp_dirs(), "the killed run should have left its temporary directory"

    # The next run takes over the stale lock, cleans up and commits.
    out = run_cli("featurize", str(store), "-q").stdout
    assert "wrote version v2" in out
    assert layout.temp_dirs() == []
    assert validate_store(store) == []
