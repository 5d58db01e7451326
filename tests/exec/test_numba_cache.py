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
