"""The command line: fast start-up, teaching --help, one-line errors, JSON summaries."""

from __future__ import annotations

import json
import pickle
import subprocess
import sys

import numpy as np
import pytest

from dancedata.store.layout import StoreLayout
from dancedata.synth.aist import synth_aist
from tests.helpers import run_cli


def _modules_loaded_by(argv: list[str]) -> set[str]:
    code = (
        "import sys\n"
        f"sys.argv = {['dancedata', *argv]!r}\n"
        "from dancedata.cli.main import main\n"
        "try:\n    main()\nexcept SystemExit:\n    pass\n"
        "print('MODULES:' + ' '.join(sorted(sys.modules)))\n"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    marker = out.stdout.rindex("MODULES:")
    return set(out.stdout[marker + len("MODULES:") :].split())


@pytest.mark.parametrize(
    "argv", [["--help"], ["--version"], ["ingest", "--help"], ["featurize", "--help"]]
)
def test_help_and_version_do_not_import_heavy_libraries(argv):
    loaded = _modules_loaded_by(argv)
    for heavy in ("librosa", "zarr", "numba", "torch", "pyarrow", "scipy", "cv2"):
        assert heavy not in loaded, f"{heavy} imported by dancedata {' '.join(argv)}"


def test_version_prints_package_version():
    import dancedata

    assert run_cli("--version").stdout.strip() == f"dancedata {dancedata.__version__}"


def test_help_lists_every_contract_command():
    out = run_cli("--help").stdout
    for command in (
        "synth",
        "ingest",
        "featurize",
        "segment",
        "info",
        "versions",
        "validate",
        "export",
    ):
        assert command in out


def test_missing_input_is_one_clear_line(tmp_path):
    proc = run_cli(
        "ingest", "aist", str(tmp_path / "nope"), "--store", str(tmp_path / "s"), check=False
    )
    assert proc.returncode == 1
    lines = [line for line in proc.stderr.splitlines() if line.strip()]
    assert len(lines) == 1 and "nope" in lines[0] and "no such directory" in lines[0]
    assert "Traceback" not in proc.stderr


@pytest.mark.slow
def test_bad_pickle_fails_clearly_and_leaves_store_untouched(tmp_path):
    raw, store = tmp_path / "raw", tmp_path / "store"
    synth_aist(raw, n_sequences=3, seed=0)
    run_cli("ingest", "aist", str(raw), "--store", str(store), "-q")
    bad = sorted((raw / "motions").iterdir())[0]
    bad.write_bytes(pickle.dumps({"smpl_poses": np.zeros((10, 70), np.float32)}))
    proc = run_cli("ingest", "aist", str(raw), "--store", str(store), "-q", check=False)
    assert proc.returncode == 1
    assert bad.name in proc.stderr and "smpl_poses" in proc.stderr
    layout = StoreLayout(store)
    assert layout.committed_versions() == ["v1"] and layout.temp_dirs() == []
    # With --on-error skip the good sequences go in and the bad one is recorded.
    proc = run_cli(
        "ingest", "aist", str(raw), "--store", str(store), "-q", "--on-error", "skip", "--json"
    )
    summary = json.loads(proc.stdout)
    assert summary["version"] == "v2" and summary["counts"]["sequences"] == 2
    skipped = layout.read_manifest("v2")["skipped"]
    assert [s["path"] for s in skipped] == [str(bad)]
    assert "shape (10, 70)" in skipped[0]["error"]


@pytest.mark.slow
def test_cli_pipeline_json_summaries(tmp_path):
    raw, store = tmp_path / "raw", tmp_path / "store"
    run_cli("synth", "aist", str(raw), "--sequences", "3", "--seed", "1", "-q")
    assert (
        json.loads(
            run_cli("ingest", "aist", str(raw), "--store", str(store), "-q", "--json").stdout
        )["version"]
        == "v1"
    )
    summary = json.loads(run_cli("segment", str(store), "--json", "-q").stdout)
    assert summary["created"] and summary["counts"]["measures"] > 0
    again = run_cli("segment", str(store), "-q").stdout
    assert "already holds" in again and "v2" in again
    run_cli("validate", str(store))
    info = json.loads(run_cli("info", str(store), "--json").stdout)
    assert info["sequences"] == 3 and info["version"] == "v2"
    assert "v1" in run_cli("versions", str(store)).stdout


@pytest.mark.slow
def test_validate_flags_a_broken_store(tmp_path):
    raw, store = tmp_path / "raw", tmp_path / "store"
    synth_aist(raw, n_sequences=3, seed=0)
    run_cli("ingest", "aist", str(raw), "--store", str(store), "-q")
    import pyarrow as pa
    import pyarrow.parquet as pq

    path = store / "versions" / "v1" / "sequences.parquet"
    table = pq.read_table(path)
    pq.write_table(
        table.set_column(
            table.schema.get_field_index("n_frames"),
            "n_frames",
            pa.array([1] * table.num_rows, pa.int64()),
        ),
        path,
    )
    proc = run_cli("validate", str(store), check=False)
    assert proc.returncode == 1
    assert "frame range != n_frames" in proc.stderr


@pytest.mark.parametrize("smooth", [False, True])
def test_bvh_ingest_imports_scipy_signal_only_to_smooth(tmp_path, smooth):
    """scipy.signal (with the scipy.stats it imports) costs 0.4-0.8 s to import: a BVH ingest
    without ``--smooth-cutoff`` must not pay it, one with it imports it and still writes its
    version (the smoothed values are checked in tests/compute/test_smoothing.py)."""
    from tests.ingest.test_ingest_bvh import synthetic_bvh

    turn = np.zeros((60, 3))
    turn[::2, 0] = 4.0  # a 15 Hz zig-zag: something for the 3 Hz low-pass to remove
    bvh = synthetic_bvh(tmp_path / "zig.bvh", 30.0, turn)
    store = tmp_path / "store"
    argv = ["ingest", "bvh", str(bvh), "--store", str(store), "-q"]
    loaded = _modules_loaded_by(argv + (["--smooth-cutoff", "3"] if smooth else []))
    assert ("scipy.signal" in loaded) is smooth
    assert StoreLayout(store).latest() == "v1"


def test_metric_modules_import_without_scipy_signal():
    """The metric registry (every evaluate and experiment command's options) imports the
    metric modules; scipy.signal is imported only by the metric that finds peaks."""
    code = (
        "import sys, dancedata.metrics, dancedata.study, dancedata.ingest.generated.source\n"
        "print('scipy.signal' in sys.modules)\n"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.strip() == "False"


@pytest.fixture(scope="module")
def one_sequence_store(tmp_path_factory):
    root = tmp_path_factory.mktemp("one-sequence")
    synth_aist(root / "raw", n_sequences=1, seed=0)
    run_cli("ingest", "aist", str(root / "raw"), "--store", str(root / "store"), "-q")
    return root / "store"


@pytest.mark.parametrize("command", ["validate", "info"])
def test_commands_that_only_read_do_not_import_pandas(one_sequence_store, command):
    """Reading a store's tables never needs pandas (0.2-0.25 s to import)."""
    assert "pandas" not in _modules_loaded_by([command, str(one_sequence_store)])


def test_a_writer_has_pandas_imported_before_it_takes_the_lock(one_sequence_store, tmp_path):
    """pyarrow imports pandas while building tables; a Ctrl-C inside that import, under the
    lock, once broke the interrupted command's cleanup. So a writer imports it first."""
    import shutil

    store = tmp_path / "store"
    shutil.copytree(one_sequence_store, store)
    code = (
        "import sys\n"
        "from dancedata.store import lock\n"
        "seen = []\n"
        "take = lock.StoreLock.acquire\n"
        "def acquire(self):\n"
        "    seen.append('pandas' in sys.modules)\n"
        "    return take(self)\n"
        "lock.StoreLock.acquire = acquire\n"
        f"sys.argv = ['dancedata', 'segment', {str(store)!r}, '-q']\n"
        "from dancedata.cli.main import main\n"
        "try:\n    main()\nexcept SystemExit:\n    pass\n"
        "print('SEEN', seen)\n"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    seen = out.stdout[out.stdout.rindex("SEEN") + 4 :].strip()
    assert seen.startswith("[True") and "False" not in seen, out.stdout + out.stderr
    assert StoreLayout(store).latest() == "v2"
