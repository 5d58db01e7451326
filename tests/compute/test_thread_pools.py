"""dancedata.compute.thread_pools: one kept threadpoolctl controller, checked against
threadpoolctl's own report of every pool's thread count, in a fresh interpreter whose pools
start at two threads (the suite's workers pin theirs to one)."""

from __future__ import annotations

import json
import os
import subprocess
import sys

from dancedata.exec.threads import thread_env

SCRIPT = r"""
import json, sys
import numpy  # its OpenBLAS: the first pool
from threadpoolctl import threadpool_info
from dancedata.compute.thread_pools import one_thread, thread_pools
from dancedata.exec.threads import single_threaded

def counts():
    return sorted((p["filepath"].rsplit("/", 1)[-1], p["num_threads"]) for p in threadpool_info())

out = {"before": counts()}
first = thread_pools()
with one_thread():
    out["inside"] = counts()
out["after"] = counts()
out["kept"] = thread_pools() is first
import scipy.linalg  # scipy's own OpenBLAS: a pool loaded after the controller was made
with one_thread("blas"):
    out["inside_after_import"] = counts()
out["remade"] = thread_pools() is not first
with single_threaded():
    out["single_threaded"] = counts()
out["restored"] = counts()
print(json.dumps(out))
"""


def test_one_thread_limits_every_pool_and_a_pool_loaded_later():
    env = {**os.environ, **thread_env(2)}
    proc = subprocess.run(
        [sys.executable, "-c", SCRIPT], env=env, capture_output=True, text=True, check=True
    )
    out = json.loads(proc.stdout)
    assert out["before"] and all(n == 2 for _, n in out["before"]), out["before"]
    assert all(n == 1 for _, n in out["inside"]), out["inside"]
    assert out["after"] == out["before"]
    assert out["kept"], "the controller was made again with no module imported since"
    assert out["remade"], "modules were imported: the controller must be made again"
    pools = out["inside_after_import"]
    assert len(pools) > len(out["before"]), f"scipy's OpenBLAS not loaded: {pools}"
    assert all(n == 1 for _, n in pools), pools
    assert all(n == 1 for _, n in out["single_threaded"]), out["single_threaded"]
    assert all(n == 2 for _, n in out["restored"]), out["restored"]
