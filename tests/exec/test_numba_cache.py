"""Worker processes of one pool compile into numba cache folders of their own (a shared folder
written by two compiles at once can crash every later run: numba issue 10128)."""

from __future__ import annotations

import os
import time
from pathlib import Path

import pytest

from dancedata.exec.executors import ProcessExecutor
from dancedata.exec.numba_cache import dask_worker_cache_dir, numba_cache_base, slot_cache_dir


def _where_numba_caches(_: int) -> tuple[int, str, str]:
    """In a worker: its pid, the variable and the folder numba itself took when imported."""
    import numba

    time.sleep(0.3)  # keep this worker busy so the other one takes the next task
    return os.getpid(), os.environ["NUMBA_CACHE_DIR"], numba.config.CACHE_DIR


def test_each_worker_slot_has_its_own_numba_cache(tmp_path, monkeypatch) -> None:
    monkeypatch.setenv("NUMBA_CACHE_DIR", str(tmp_path / "numba"))
    assert numba_cache_base() == tmp_path / "numba"
    with ProcessExecutor(2) as executor:
        results = [r for _, r in executor.map_unordered(_where_numba_caches, list(range(6)))]
    by_pid: dict[int, set[str]] = {}
    for pid, variable, taken in results:
        assert variable == taken  # set before numba was imported, so numba uses it
        by_pid.setdefault(pid, set()).add(taken)
    assert len(by_pid) == 2 and all(len(folders) == 1 for folders in by_pid.values())
    folders = {next(iter(f)) for f in by_pid.values()}
    assert folders == {str(slot_cache_dir(tmp_path / "numba", k)) for k in (0, 1)}


def test_default_base_follows_xdg(tmp_path, monkeypatch) -> None:
    monkeypatch.delenv("NUMBA_CACHE_DIR", raising=False)
    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path))
    assert numba_cache_base() == tmp_path / "dancedata" / "numba"
    assert slot_cache_dir(Path("/x"), 3) == Path("/x/worker-3")
    with pytest.raises(ValueError):
        slot_cache_dir(Path("/x"), -1)


@pytest.mark.slow
def test_each_worker_of_a_local_dask_cluster_has_its_own_numba_cache(tmp_path, monkeypatch):
    """``--dask local:N`` starts N workers at once: each must compile into a folder of its own."""
    pytest.importorskip("distributed")
    from dancedata.exec.executors import DaskExecutor

    monkeypatch.setenv("NUMBA_CACHE_DIR", str(tmp_path / "numba"))
    with DaskExecutor("local:2") as executor:
        taken = executor.client.run(_numba_cache_of_this_process)
    expected = {str(dask_worker_cache_dir(tmp_path / "numba", k)) for k in (0, 1)}
    assert sorted(taken.values()) == sorted(expected)
    assert len(taken) == 2


def _numba_cache_of_this_process() -> str:
    import numba

    return numba.config.CACHE_DIR


def test_a_dask_worker_name_is_kept_to_one_safe_folder_name(tmp_path) -> None:
    assert dask_worker_cache_dir(tmp_path, 3) == tmp_path / "dask-3"
    assert dask_worker_cache_dir(tmp_path, "../../x y") == tmp_path / "dask-______x_y"
    assert dask_worker_cache_dir(tmp_path, "") == tmp_path / "dask-worker"


def _compile_and_call(folder: str, src: Path) -> tuple[int, int]:
    """In a fresh process with ``NUMBA_CACHE_DIR=folder``: compile (or load) the cached function
    of the module in ``src``, and return its result and numba's count of
    functions it compiled in this process."""
    import subprocess
    import sys

    code = (
        "import sys; sys.path.insert(0, sys.argv[1]); import kernel; "
        "print(kernel.triple(14), len(kernel.triple.stats.cache_misses))"
    )
    out = subprocess.run(
        [sys.executable, "-c", code, str(src)],
        env={**os.environ, "NUMBA_CACHE_DIR": folder},
        capture_output=True,
        text=True,
        check=True,
    ).stdout.split()
    return int(out[0]), int(out[1])


def test_a_new_slot_is_seeded_with_what_was_compiled_before(tmp_path) -> None:
    """A new slot folder starts as a copy of the fullest sibling: its process loads the compiled
    function instead of compiling it (numba's own miss counter says which happened)."""
    from dancedata.exec.numba_cache import numba_entries, seed_cache_folder, seed_sources

    src = tmp_path / "src"
    src.mkdir()
    (src / "kernel.py").write_text(
        "import numba\n\n@numba.njit(cache=True)\ndef triple(x):\n    return 3 * x\n"
    )
    base = tmp_path / "numba"
    assert _compile_and_call(str(base), src) == (42, 1)  # compiled: one miss
    assert _compile_and_call(str(base), src) == (42, 0)  # loaded from the cache
    slot = slot_cache_dir(base, 0)
    assert seed_cache_folder(slot, seed_sources(base)) == 2  # the index and the data file
    assert [e.name for e in numba_entries(slot)] == [e.name for e in numba_entries(base)]
    assert not list(slot.glob(".seed-*"))
    assert _compile_and_call(str(slot), src) == (42, 0)  # loaded, not compiled
    assert seed_cache_folder(slot, seed_sources(base)) == 0  # already holds functions
    # Nothing to take from: an empty folder stays empty (its process compiles).
    assert seed_cache_folder(tmp_path / "other" / "worker-0", [tmp_path / "nothing"]) == 0
    assert _compile_and_call(str(tmp_path / "fresh"), src) == (42, 1)


def test_a_seed_skips_links_and_files_still_being_written(tmp_path) -> None:
    from dancedata.exec.numba_cache import numba_entries, seed_cache_folder

    source = tmp_path / "base"
    entry = source / f"src_{'a' * 40}"
    entry.mkdir(parents=True)
    (entry / "f-1.py311.nbi").write_bytes(b"index")
    (entry / "f-1.py311.1.nbc").write_bytes(b"data")
    (entry / "f-1.py311.1.nbc.tmp.0123456789abcdef").write_bytes(b"half")
    outside = tmp_path / "outside"
    outside.mkdir()
    (source / f"link_{'b' * 40}").symlink_to(outside, target_is_directory=True)
    (source / "not-numba").mkdir()
    assert [e.name for e in numba_entries(source)] == [entry.name]
    target = tmp_path / "slot"
    assert seed_cache_folder(target, [source]) == 2
    copied = sorted(p.name for p in (target / entry.name).iterdir())
    assert copied == ["f-1.py311.1.nbc", "f-1.py311.nbi"]
    assert sorted(p.name for p in target.iterdir()) == [entry.name]


def _use_machine_cache_in_a_fresh_process(env: dict[str, str]) -> list[str]:
    """``use_machine_cache()`` in a new interpreter (numba not imported yet, as in a starting
    ``dancedata`` command): its return value and the ``NUMBA_CACHE_DIR`` it leaves."""
    import subprocess
    import sys

    code = "import os; from dancedata.exec.numba_cache import use_machine_cache as u; "
    code += "print(u(), os.environ['NUMBA_CACHE_DIR'])"
    return subprocess.run(
        [sys.executable, "-c", code], env=env, check=True, capture_output=True, text=True
    ).stdout.split()


def test_the_command_caches_where_worker_slots_seed_from(tmp_path) -> None:
    """The ``dancedata`` command points numba at ~/.cache/dancedata/numba (XDG) when
    NUMBA_CACHE_DIR is unset, so what a serial run compiles seeds the worker slots of the next
    parallel one (numba's default, __pycache__ beside each source, is out of their reach); an
    explicit NUMBA_CACHE_DIR is kept."""
    import subprocess
    import sys

    from dancedata.exec.numba_cache import numba_entries
    from dancedata.synth.aist import synth_aist

    raw, store = tmp_path / "raw", tmp_path / "store"
    synth_aist(raw, n_sequences=1, seed=3)
    xdg = tmp_path / "xdg"
    env = {k: v for k, v in os.environ.items() if k != "NUMBA_CACHE_DIR"}
    env.update(XDG_CACHE_HOME=str(xdg), DANCEDATA_CACHE=str(tmp_path / "fc"))
    cli = [sys.executable, "-m", "dancedata.cli"]
    for argv in (["ingest", "aist", str(raw), "--store", str(store)], ["featurize", str(store)]):
        extra = ["--no-audio"] if argv[0] == "featurize" else []  # motion kernels only
        subprocess.run([*cli, *argv, "-q", *extra], env=env, check=True, capture_output=True)
    assert numba_entries(xdg / "dancedata" / "numba"), "featurize compiled nothing into the base"
    mine = str(tmp_path / "mine")
    assert _use_machine_cache_in_a_fresh_process({**env, "NUMBA_CACHE_DIR": mine}) == [
        "None",
        mine,
    ]
    assert _use_machine_cache_in_a_fresh_process(env) == [str(xdg / "dancedata" / "numba")] * 2


def test_an_empty_base_is_seeded_from_its_worker_slots(tmp_path) -> None:
    """A first serial run after parallel ones loads what the worker slots compiled."""
    xdg = tmp_path / "xdg"
    base = xdg / "dancedata" / "numba"
    entry = base / "worker-1" / f"src_{'c' * 40}"
    entry.mkdir(parents=True)
    (entry / "f-1.py311.nbi").write_bytes(b"index")
    (entry / "f-1.py311.1.nbc").write_bytes(b"data")
    env = {k: v for k, v in os.environ.items() if k != "NUMBA_CACHE_DIR"}
    assert (
        _use_machine_cache_in_a_fresh_process({**env, "XDG_CACHE_HOME": str(xdg)})
        == [str(base)] * 2
    )
    assert sorted(p.name for p in (base / entry.name).iterdir()) == [
        "f-1.py311.1.nbc",
        "f-1.py311.nbi",
    ]


def test_cache_warm_compiles_what_featurize_runs_into_the_machine_cache(tmp_path) -> None:
    """``dancedata cache warm`` fills the machine's numba folder with what featurize compiles:
    from a copy of this worker's folder with two of dancedata's NMFD kernels removed (so the
    command must compile them, not load them; the others would cost ~15 s more), it writes
    them back, leaves no sample behind, and a second run compiles nothing more."""
    import json
    import shutil
    import subprocess
    import sys

    from dancedata.exec.numba_cache import numba_entries

    base = tmp_path / "xdg" / "dancedata" / "numba"
    slots = shutil.ignore_patterns("worker-*", "dask-*", "concurrent-*")
    shutil.copytree(os.environ["NUMBA_CACHE_DIR"], base, symlinks=True, ignore=slots)
    removed = ("jit_kernels.kl_ratio-", "jit_kernels.divide_where_above-")
    for entry in numba_entries(base):
        for path in entry.iterdir():
            if path.name.startswith(removed):
                path.unlink()
    scratch = tmp_path / "tmp"
    scratch.mkdir()
    env = {k: v for k, v in os.environ.items() if k != "NUMBA_CACHE_DIR"}
    env.update(XDG_CACHE_HOME=str(tmp_path / "xdg"), TMPDIR=str(scratch))
    argv = [sys.executable, "-m", "dancedata.cli", "cache", "warm", "--json"]

    def warm() -> dict:
        proc = subprocess.run(argv, env=env, capture_output=True, text=True, timeout=300)
        assert proc.returncode == 0, proc.stderr[-2000:]
        return json.loads(proc.stdout)

    first = warm()
    assert first["numba_cache_dir"] == str(base)
    found = {p.name.rsplit("-", 1)[0] for e in numba_entries(base) for p in e.glob("*.nbi")}
    assert {"jit_kernels.kl_ratio", "jit_kernels.divide_where_above"} <= found
    assert {"jit_kernels.beat_track_dp", "jit_kernels.window_median", "utils._localmax",
            "rotation_kernels._convert_all", "guf-beat.__beat_track_dp"} <= found  # fmt: skip
    assert first["compiled_files_after"] >= first["compiled_files_before"] + 4  # 2 × (nbi, nbc)
    assert list(scratch.iterdir()) == []  # the sample and its store are gone
    second = warm()
    assert second["compiled_files_before"] == second["compiled_files_after"]
    assert second["compiled_files_after"] == first["compiled_files_after"]
