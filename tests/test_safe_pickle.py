"""The restricted unpickler loads numpy data and refuses everything else without running it."""

from __future__ import annotations

import os
import pickle
from pathlib import Path

import numpy as np
import pytest

from dancedata.errors import InputError
from dancedata.safe_pickle import UnsafePickleError, load_restricted, loads_restricted


class _CreatesFile:
    """A pickle payload that would create a file if it were ever executed."""

    def __init__(self, target: Path) -> None:
        self.target = target

    def __reduce__(self):
        return (os.system, (f"touch {self.target}",))


def test_numpy_arrays_scalars_and_containers_round_trip():
    value = {
        "a": np.arange(12, dtype=np.float32).reshape(3, 4),
        "b": [np.float64(1.5), 2, "x", (1, 2)],
        "c": np.array([1], dtype=np.int64),
    }
    for protocol in (2, 3, 4, 5):
        back = loads_restricted(pickle.dumps(value, protocol=protocol))
        np.testing.assert_array_equal(back["a"], value["a"])
        assert back["a"].dtype == np.float32
        assert back["b"][0] == 1.5 and back["b"][2] == "x"


def test_malicious_pickle_is_refused_and_never_executed(tmp_path):
    target = tmp_path / "pwned"
    path = tmp_path / "evil.pkl"
    path.write_bytes(pickle.dumps({"smpl_poses": _CreatesFile(target)}))
    with pytest.raises(UnsafePickleError) as info:
        load_restricted(path)
    assert "posix.system" in str(info.value) or "os.system" in str(info.value)
    assert str(path) in str(info.value)
    assert not target.exists()
    # Sanity check that the payload is real: a plain pickle.loads would have run it.
    pickle.loads(path.read_bytes())
    assert target.exists()


@pytest.mark.parametrize(
    "module,name",
    [("builtins", "eval"), ("subprocess", "Popen"), ("numpy", "load"), ("builtins", "getattr")],
)
def test_other_globals_are_refused(module, name):
    payload = f"c{module}\n{name}\n(S'1'\ntR.".encode()
    with pytest.raises(UnsafePickleError):
        loads_restricted(payload)


def test_truncated_pickle_gives_input_error(tmp_path):
    data = pickle.dumps({"x": np.zeros((100, 72), np.float32)}, protocol=4)
    path = tmp_path / "cut.pkl"
    path.write_bytes(data[: len(data) // 2])
    with pytest.raises(InputError) as info:
        load_restricted(path)
    assert str(path) in str(info.value)


@pytest.mark.real_data
def test_real_aist_pickles_load(real_data):
    for path in sorted((real_data / "aist" / "motions").glob("*.pkl")):
        data = load_restricted(path)
        assert data["smpl_poses"].shape[1] == 72
        assert data["smpl_poses"].dtype == np.float32
