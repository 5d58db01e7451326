"""The restricted unpickler loads numpy data exactly as pickle does, and refuses everything else
without running it and without letting the file choose how memory is used."""

from __future__ import annotations

import os
import pickle
import subprocess
import sys
import time
from collections import OrderedDict
from pathlib import Path

import numpy as np
import pytest

from dancedata.errors import InputError
from dancedata.io.safe_pickle import (
    PickleLimits,
    UnsafePickleError,
    load_restricted,
    loads_restricted,
)
from tests.data.bad import make_corpus as mc


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


# -- loads exactly what pickle loads -----------------------------------------------------------
def _same(ours: object, theirs: object) -> bool:
    """Equal type, structure, dtype, shape, memory layout and bytes (NaN equal to NaN)."""
    if isinstance(theirs, np.ndarray):
        return (
            isinstance(ours, np.ndarray)
            and ours.dtype == theirs.dtype
            and ours.shape == theirs.shape
            and ours.tobytes("A") == theirs.tobytes("A")
            and ours.flags.c_contiguous == theirs.flags.c_contiguous
            and ours.flags.f_contiguous == theirs.flags.f_contiguous
        )
    if isinstance(theirs, dict):
        return (
            type(ours) is type(theirs)
            and list(ours) == list(theirs)
            and all(_same(ours[k], theirs[k]) for k in theirs)
        )
    if isinstance(theirs, (list, tuple)):
        return (
            type(ours) is type(theirs)
            and len(ours) == len(theirs)
            and all(map(_same, ours, theirs))
        )
    if isinstance(theirs, (float, np.floating)) and theirs != theirs:
        return type(ours) is type(theirs) and ours != ours
    return type(ours) is type(theirs) and ours == theirs


def _numeric_values() -> dict:
    rng = np.random.default_rng(11)
    return {
        "f8_big_endian": rng.normal(size=(3, 4)).astype(">f8"),
        "f4_fortran": np.asfortranarray(rng.normal(size=(3, 5)).astype(np.float32)),
        "i2_empty": np.zeros((0, 7), np.int16),
        "zero_d": np.array(3.0),
        "u1": np.arange(5, dtype=np.uint8),
        "u8": np.array([2**64 - 1, 0], dtype=np.uint64),
        "bool": np.array([True, False]),
        "f2": np.arange(4, dtype=np.float16),
        "nan": np.array([np.nan, -np.inf, 1e300]),
        "non_contiguous": np.arange(20.0).reshape(4, 5)[:, ::2],
        "scalars": [np.float64(1.5), np.int32(-3), np.bool_(True), np.float32(np.nan), np.uint8(9)],
        "plain": [2, "x", (1, 2), None, True, 1.25, 10**30, -5, {"k": [[1, [2, (3,)]]]}],
        "ordered": OrderedDict(a=1, b=np.arange(2)),
    }


@pytest.mark.parametrize("protocol", range(pickle.HIGHEST_PROTOCOL + 1))
def test_numeric_values_load_exactly_as_pickle_loads_them(protocol):
    value = _numeric_values()
    data = pickle.dumps(value, protocol=protocol)
    ours, theirs = loads_restricted(data), pickle.loads(data)
    assert _same(ours, theirs)
    assert ours["f8_big_endian"].dtype == theirs["f8_big_endian"].dtype  # native, like numpy
    assert all(a.flags.owndata for a in ours.values() if isinstance(a, np.ndarray))


def test_protocol_4_and_5_containers_load():
    value = {"s": {1, 2}, "fs": frozenset({3}), "b": b"by"}
    for protocol in (4, 5):
        data = pickle.dumps(value, protocol=protocol)
        assert loads_restricted(data) == pickle.loads(data)
    data = pickle.dumps(bytearray(b"q"), protocol=5)  # BYTEARRAY8 (protocol 4 calls bytearray)
    assert loads_restricted(data) == bytearray(b"q")


@pytest.mark.real_data
def test_real_aist_pickles_load_bit_identically(real_data):
    paths = sorted((real_data / "aist").glob("*/*.pkl"))
    assert len(paths) >= 10
    for path in paths:
        with open(path, "rb") as handle:
            assert _same(load_restricted(path), pickle.load(handle)), path


# -- memory safety: each hostile class is refused before it allocates --------------------------
def _refusal(data: bytes, limits: PickleLimits | None = None) -> str:
    with pytest.raises(UnsafePickleError) as info:
        loads_restricted(data, "x.pkl", **({"limits": limits} if limits else {}))
    message = str(info.value)
    assert "\n" not in message and message.startswith("x.pkl: unsafe pickle: refused ")
    return message


def _hostile(name: str) -> bytes:
    return next(data for case, data, _, _ in mc.hostile_pickles() if case == name)


def test_dtype_state_numpy_would_not_write_is_refused():
    f8 = mc._op_dtype("f8")
    for state in (
        (3, "|", None, None, None, 8, 1, 1),  # object flags on a float
        (3, "<", None, None, None, -1, -1, 0x10),  # NEEDS_PYAPI
        (3, "<", (f8, (2,)), None, None, -1, -1, 0),  # a subarray
        (3, "<", None, ("a",), None, -1, -1, 0),  # names
        (3, "<", None, None, None, 16, -1, 0),  # a wrong item size
        (4, "<", None, None, None, -1, -1, 0, None),  # version 4 (metadata)
        (3, "!", None, None, None, -1, -1, 0),  # not a byte order
        (3, "|", None, None, None, -1, -1, 0),  # "not applicable" on an 8-byte type
    ):
        ops = mc._op_plain(state)
        if isinstance(state[2], tuple):  # numpy's dtype object cannot be pickled by _op_plain
            ops = mc._op_tuple(
                mc._op_int(3), mc._op_str("<"), mc._op_tuple(f8, mc._op_shape((2,))), b"NN",
                mc._op_int(-1), mc._op_int(-1), mc._op_int(0),
            )  # fmt: skip
        assert "dtype state" in _refusal(b"\x80\x04" + mc._op_dtype("f8", ops) + b".")
    for typestr in ("O8", "V8", "U3", "S3", "c16", "f16", "M8", "m8", "<f8"):
        assert f"dtype {typestr!r}" in _refusal(b"\x80\x04" + mc._op_dtype(typestr) + b".")


def test_numpy_ndarray_is_never_called():
    f4 = mc._op_dtype("f4")
    for extra in ((), (mc._op_bytes(b"\0" * 4), mc._op_int(0), mc._op_shape((0,)))):
        data = b"\x80\x04" + mc._op_ndarray_call((10**6,), f4, *extra) + b"."
        assert "numpy.ndarray" in _refusal(data)
    for name in ("evil_ndarray_uninitialised", "evil_ndarray_huge", "evil_zero_stride_view"):
        assert "numpy.ndarray" in _refusal(_hostile(name))


def test_array_bytes_must_match_the_declared_shape_before_allocation():
    f8 = mc._op_dtype("f8")
    for shape, data in (((4, 2), b"\0" * 63), ((4, 2), b"\0" * 65), ((10**12, 10**6), b"abc")):
        array = mc._op_reconstructed_array(shape, f8, data)
        assert "bytes" in _refusal(b"\x80\x04" + array + b".")
    for shape in ((-1, 2), (2.0,), ("2",), tuple([1] * 33), (2**41,)):
        array = mc._op_reconstructed_array((), f8, b"")
        array = array.replace(mc._op_shape(()), mc._op_plain(shape), 1)
        assert "array shape" in _refusal(b"\x80\x04" + array + b".")
    # _frombuffer (protocol 5) is held to the same rule
    frombuffer = (
        mc._op_global("numpy._core.numeric", "_frombuffer")
        + mc._op_tuple(mc._op_bytes(b"\0" * 12), f8, mc._op_shape((10**9,)), mc._op_str("C"))
        + b"R."
    )
    assert "needs 8000000000 bytes" in _refusal(b"\x80\x05" + frombuffer)
    # _reconstruct itself is only ever asked for an empty array of numpy.ndarray
    huge = mc._op_global("numpy.core.multiarray", "_reconstruct") + mc._op_tuple(
        mc._op_global("numpy", "ndarray"), mc._op_shape((10**9,)), mc._op_bytes(b"b")
    )
    assert "_reconstruct with shape" in _refusal(b"\x80\x04" + huge + b"R.")


def test_a_memoised_buffer_cannot_be_reused_to_build_gigabytes():
    f8 = mc._op_dtype("f8")
    first = mc._op_reconstructed_array((1000,), f8, b"\0" * 8000)
    data_at = first.index(mc._op_bytes(b"\0" * 8000))
    memoised = first[:data_at] + mc._op_bytes(b"\0" * 8000) + b"q\x01" + first[data_at + 8005 :]
    again = first[:data_at] + b"h\x01" + first[data_at + 8005 :]
    data = b"\x80\x04(" + memoised + again * 50 + b"l."
    assert "more array bytes than twice" in _refusal(data)
    ok = b"\x80\x04(" + memoised + again + b"l."
    assert len(loads_restricted(ok)) == 2  # reused once: within the budget


def test_memo_index_and_nesting_are_bounded_without_crash_or_allocation():
    assert "memo index 268435456" in _refusal(_hostile("evil_long_binput"))
    assert "memo index" in _refusal(b"\x80\x04Np-1\n.")
    assert "nested more than 32 deep" in _refusal(_hostile("evil_deep_nesting"))
    assert "nested more than 32 deep" in _refusal(b"\x80\x04" + b"(" * 100_000)
    # Lists nested by APPEND after they were themselves nested: caught over the whole result.
    chain = b"".join(b"]q" + bytes([k]) for k in range(40))
    links = b"".join(b"h" + bytes([k]) + b"h" + bytes([k + 1]) + b"a0" for k in range(39))
    assert "nested more than 32 deep" in _refusal(b"\x80\x04" + chain + links + b"0h\x00.")
    assert "contains itself" in _refusal(b"\x80\x04]q\x00h\x00a.")


def test_stack_items_integers_opcodes_and_file_size_are_bounded():
    small = PickleLimits(max_stack=100, max_items=100, max_opcodes=1000, max_file_bytes=5000)
    assert "values on the stack" in _refusal(b"\x80\x04" + b"N" * 200 + b".", small)
    appends = b"\x80\x04]" + b"Na" * 150 + b"."
    assert "container items" in _refusal(appends, small)
    assert "opcodes" in _refusal(b"\x80\x04" + b"N0" * 600 + b"N.", small)
    assert "larger than 5000 bytes" in _refusal(b"\x80\x04" + b"N0" * 3000 + b"N.", small)
    assert "integer of" in _refusal(b"\x80\x04\x8b\x00\x00\x00\x01" + b"\0" * 2**24 + b".")
    assert "INT of" in _refusal(b"I" + b"9" * 1000 + b"\n.")


def test_file_over_the_size_limit_is_refused_before_it_is_read(tmp_path):
    path = tmp_path / "big.pkl"
    path.write_bytes(b"\x80\x04N." + b"\0" * 5000)
    with pytest.raises(UnsafePickleError, match="refused a file of 5004 bytes"):
        load_restricted(path, PickleLimits(max_file_bytes=4096))


@pytest.mark.parametrize(
    "data,expect",
    [
        (b"\x80\x04P", "persistent id"),
        (b"\x80\x04NQ", "persistent id"),
        (b"\x80\x04\x82\x01", "extension code"),
        (b"\x80\x05\x97", "out-of-band buffer"),
        (b"\x80\x05N\x98", "out-of-band buffer"),
        (b"(inumpy\ndtype\n.", "INST of numpy.dtype"),
        (b"(cnumpy\ndtype\no.", "OBJ"),
        (b"\x80\x04}N\x81.", "to create"),
        (b"\x80\x04}Nb.", "to set the state of a dict"),
        (b"\x80\x04X\x01\x00\x00\x00a)R.", "to call a str"),
        (b"\x80\x04cnumpy\ndtype\n.", "includes numpy.dtype itself"),
        (b"\x80\x04cbuiltins\nbytes\nX\x01\x00\x00\x00a\x85R.", "bytes(...) with arguments"),
        (b"\x80\x04c_codecs\nencode\nX\x01\x00\x00\x00aX\x04\x00\x00\x00utf8\x86R.", "_codecs"),
    ],
)
def test_opcodes_and_calls_numpy_pickles_never_need_are_refused(data, expect):
    assert expect in _refusal(data)


def test_an_array_used_before_its_state_is_refused():
    head = mc._op_global("numpy.core.multiarray", "_reconstruct") + mc._op_tuple(
        mc._op_global("numpy", "ndarray"), mc._op_shape((0,)), mc._op_bytes(b"b")
    )
    assert "before its state" in _refusal(b"\x80\x04" + head + b"R\x85.")
    state = mc._op_tuple(
        mc._op_int(1), mc._op_shape((1,)), mc._op_dtype("u1"), b"\x89", mc._op_bytes(b"x")
    )
    twice = b"\x80\x04" + head + b"R2" + state + b"b0" + state + b"b."  # DUP, BUILD, POP, BUILD
    assert "second state" in _refusal(twice)
    assert "state of a ndarray" in _refusal(b"\x80\x04" + head + b"R" + (state + b"b") * 2 + b".")


@pytest.mark.parametrize(
    "data,expect",
    [
        (b"", "the file is empty"),
        (b"\x80\x04N", "without its STOP"),
        (
            b"\x80\x04\x8e" + (2**62).to_bytes(8, "little") + b"abc.",
            "needs 4611686018427387904 bytes",
        ),
        (b"\x80\x04\x95" + (2**40).to_bytes(8, "little") + b"N.", "a frame of"),
        (b"\x80\x04h\x07.", "memo slot 7 is read before"),
        (b"\x80\x04t.", "no MARK"),
        (b"\x80\x04\xff.", "unknown opcode 0xff"),
        (b"\x80\x09N.", "unsupported pickle protocol 9"),
        (b"\x80\x04NN\x93.", "two strings"),
    ],
)
def test_malformed_pickles_are_one_unreadable_line(data, expect):
    with pytest.raises(InputError) as info:
        loads_restricted(data, "x.pkl")
    message = str(info.value)
    assert "\n" not in message and message.startswith("x.pkl: unreadable pickle")
    assert expect in message


_CHILD = """
import resource, sys
from dancedata.errors import DancedataError
from dancedata.io.safe_pickle import load_restricted
try:
    load_restricted(sys.argv[1])
    code = 0
except DancedataError as exc:
    print(f"error: {exc}", file=sys.stderr)
    code = 1
# VmHWM, not ru_maxrss: ru_maxrss survives exec, so a child would report pytest's own peak
print(int(open('/proc/self/status').read().split('VmHWM:')[1].split()[0]))
sys.exit(code)
"""


@pytest.mark.slow
@pytest.mark.parametrize("name", [case for case, *_ in mc.hostile_pickles()])
def test_each_hostile_class_exits_1_with_one_line_in_a_subprocess(tmp_path, name):
    """Before this unpickler: SIGSEGV (object flags, deep nesting), 2.3 GB (352-byte ndarray
    call), 4.2 GB (LONG_BINPUT 2**28). Now one line, exit 1, and the child stays small."""
    path = tmp_path / f"{name}.pkl"
    path.write_bytes(_hostile(name))
    baseline = subprocess.run(
        [sys.executable, "-c", "import resource, numpy; "
         "print(int(open('/proc/self/status').read().split('VmHWM:')[1].split()[0]))"],
        capture_output=True, text=True, check=True,
    )  # fmt: skip
    began = time.monotonic()
    proc = subprocess.run(
        [sys.executable, "-c", _CHILD, str(path)], capture_output=True, text=True, timeout=120
    )
    assert proc.returncode == 1, (proc.returncode, proc.stderr[-2000:])
    assert proc.stderr.count("\n") == 1 and proc.stderr.startswith(f"error: {path}: unsafe pickle")
    grew_kb = int(proc.stdout.split()[-1]) - int(baseline.stdout.split()[-1])
    assert grew_kb < 100_000, f"the child grew by {grew_kb} kB"
    assert time.monotonic() - began < 30


def test_dict_keys_whose_hashes_can_be_made_to_collide_are_refused():
    """20,000 ints that are multiples of 2**61 - 1 share one hash: a plain dict of them takes
    seconds, a million of them hours. Keys are strings, bytes, small ints or tuples of strings."""
    modulus = 2**61 - 1
    key = b"\x8a\x10" + (3 * modulus).to_bytes(16, "little", signed=True)
    for container in (b"}" + key + b"Ns", b"\x8f(" + key + b"\x90", b"(" + key + b"\x91"):
        assert "as a dict key or set item" in _refusal(b"\x80\x04" + container + b".")
    for key in (b"G?\xf0\x00\x00\x00\x00\x00\x00", b"K\x01K\x02\x86"):  # a float, a tuple of ints
        assert "as a dict key" in _refusal(b"\x80\x04}" + key + b"Ns.")
    ok = {"s": 1, b"b": 2, 7: 3, -(2**40): 4, None: 5, True: 6, ("a", b"b", None): 7}
    assert loads_restricted(pickle.dumps(ok, protocol=4)) == ok
