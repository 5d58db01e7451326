"""Fuzz targets: a strategy of inputs and a check each input must pass.

Every check encodes one reader's contract on hostile input: return a well-formed result, or raise
:class:`~dancedata.errors.InputError` with one line naming the file; never another exception,
never a hang (:func:`tests.fault_strategies.within`), never code execution.
"""

from __future__ import annotations

import atexit
import math
import pickle
import shutil
import struct
import tempfile
import warnings
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
from hypothesis import strategies as st

from dancedata.errors import InputError
from tests.data.bad.make_corpus import good_motion
from tests.fault_strategies import Hang, bvh_documents, mutated_bvh, within
from tests.io.test_faults_bvh_hypothesis import check_bvh_bytes, check_valid_doc

_SCRATCH = Path(tempfile.mkdtemp(prefix="dancedata-fuzz-"))
atexit.register(shutil.rmtree, _SCRATCH, ignore_errors=True)


@dataclass(frozen=True)
class Target:
    """One fuzz target: ``check(example)`` for examples drawn from ``strategy``."""

    name: str
    strategy: st.SearchStrategy
    check: Callable[[Any], None]
    doc: str


def _one_line(exc: InputError, path: Path) -> None:
    message = str(exc)
    assert "\n" not in message, message
    assert message.startswith(str(path)), message


# -- pickles -----------------------------------------------------------------------------------
_GOOD_PICKLE = pickle.dumps(good_motion(24), protocol=4)


@st.composite
def _mutated_pickles(draw: st.DrawFn) -> bytes:
    data = bytearray(draw(st.sampled_from([_GOOD_PICKLE, pickle.dumps(good_motion(3), 2)])))
    for _ in range(draw(st.integers(1, 4))):
        kind = draw(st.sampled_from(["byte", "truncate", "insert", "delete"]))
        pos = draw(st.integers(0, len(data)))
        if kind == "byte" and pos < len(data):
            data[pos] = draw(st.integers(0, 255))
        elif kind == "truncate":
            del data[pos:]
        elif kind == "insert":
            data[pos:pos] = draw(st.binary(min_size=1, max_size=8))
        else:
            del data[pos : pos + draw(st.integers(1, 16))]
    return bytes(data)


_PICKLES = st.one_of(
    _mutated_pickles(),
    st.binary(max_size=200).map(lambda b: b"\x80\x04" + b),  # opcode soup
)


def check_pickle(data: bytes) -> None:
    """read_motion: an AistMotion with finite (F, 24, 3) poses, or one InputError line."""
    from dancedata.io.aist import read_motion

    path = _SCRATCH / "motion.pkl"
    path.write_bytes(data)
    marker_count = len(list(_SCRATCH.iterdir()))
    with within(5.0):
        try:
            motion = read_motion(path)
        except InputError as exc:
            _one_line(exc, path)
            return
    assert motion.axis_angle.shape[1:] == (24, 3) and motion.n_frames > 0
    assert np.isfinite(motion.axis_angle).all() and np.isfinite(motion.trans_m).all()
    assert len(list(_SCRATCH.iterdir())) == marker_count  # nothing created a file


# -- pickle opcode streams (the restricted unpickler itself) -----------------------------------
_GLOBAL_NAMES = [
    ("numpy.core.multiarray", "_reconstruct"),
    ("numpy._core.multiarray", "_reconstruct"),
    ("numpy._core.multiarray", "scalar"),
    ("numpy._core.numeric", "_frombuffer"),
    ("numpy", "ndarray"),
    ("numpy", "dtype"),
    ("collections", "OrderedDict"),
    ("_codecs", "encode"),
    ("builtins", "bytes"),
    ("builtins", "eval"),
    ("os", "system"),
    ("numpy", "frombuffer"),
]
_TYPESTRS = ["f4", "f8", "i8", "u1", "b1", "f2", "O8", "V8", "U3", "c8", "M8", "x"]


def _uint(n: int) -> st.SearchStrategy[bytes]:
    edge = [0, 1, 2, 3, 255, 2**8 * n - 1, 2**28, 2**31 - 1]
    values = st.one_of(st.integers(0, 2 ** (8 * n) - 1), st.sampled_from(edge))
    return values.map(lambda v: (v % 2 ** (8 * n)).to_bytes(n, "little"))


def _sized(n: int) -> st.SearchStrategy[bytes]:
    """A length-prefixed payload; sometimes the length lies (longer or shorter)."""

    @st.composite
    def build(draw: st.DrawFn) -> bytes:
        payload = draw(st.one_of(st.binary(max_size=40), st.sampled_from([b"b", b"latin1", b"f4"])))
        length = len(payload)
        if draw(st.integers(0, 9)) == 0:
            length = draw(st.sampled_from([0, length + 1, 2 ** (8 * min(n, 4)) - 1, 2**31 - 1]))
        return (length % 2 ** (8 * n)).to_bytes(n, "little") + payload

    return build()


def _line(values: st.SearchStrategy[str]) -> st.SearchStrategy[bytes]:
    return values.map(lambda text: text.encode("utf-8", "surrogatepass") + b"\n")


_DECIMAL = st.one_of(
    st.integers(-(10**30), 10**30).map(str), st.sampled_from(["00", "01", "x", "9" * 300])
)
_ARGUMENTS: dict[str, st.SearchStrategy[bytes]] = {
    "uint1": _uint(1),
    "uint2": _uint(2),
    "uint4": _uint(4),
    "uint8": _uint(8),
    "int4": _uint(4),
    "float8": st.floats(allow_nan=True).map(lambda x: struct.pack(">d", x)),
    "long1": _sized(1),
    "long4": _sized(4),
    "bytes1": _sized(1),
    "bytes4": _sized(4),
    "bytes8": _sized(8),
    "bytearray8": _sized(8),
    "string1": _sized(1),
    "string4": _sized(4),
    "unicodestring1": _sized(1),
    "unicodestring4": _sized(4),
    "unicodestring8": _sized(8),
    "decimalnl_short": _line(_DECIMAL),
    "decimalnl_long": _line(_DECIMAL.map(lambda d: d + "L")),
    "floatnl": _line(st.one_of(st.floats().map(repr), st.just("nan"), st.just("1e999"))),
    "stringnl": _line(st.sampled_from(["'abc'", '"x\\x00"', "'unterminated", "''"])),
    "stringnl_noescape": _line(st.sampled_from(["numpy", "ndarray", "os"])),
    "stringnl_noescape_pair": st.sampled_from(_GLOBAL_NAMES).map(
        lambda pair: f"{pair[0]}\n{pair[1]}\n".encode()
    ),
    "unicodestringnl": _line(st.text(max_size=10).filter(lambda t: "\n" not in t)),
}


def _opcode_strategy() -> st.SearchStrategy[bytes]:
    """One opcode with an argument of the right kind (lengths and indices sometimes hostile)."""
    import pickletools

    choices = []
    for op in pickletools.opcodes:
        code = op.code.encode("latin-1")
        arg = _ARGUMENTS[op.arg.name] if op.arg is not None else st.just(b"")
        choices.append(arg.map(lambda a, code=code: code + a))
    return st.one_of(choices)


_OPCODE = _opcode_strategy()


def _numpy_snippets() -> list[bytes]:
    """Opcode runs cut from valid numpy pickles: a global, a dtype, an array state..."""
    import pickletools

    snippets = []
    for value in (np.arange(6, dtype=np.float32).reshape(2, 3), np.float64(1.5), {"k": (1, [2])}):
        for protocol in (2, 4, 5):
            data = pickle.dumps(value, protocol=protocol)
            ops = list(pickletools.genops(data))
            bounds = [pos for _, _, pos in ops] + [len(data)]
            for k in range(len(ops)):
                snippets.append(data[bounds[k] : bounds[k + 1]])
                snippets.append(data[bounds[k] : bounds[min(k + 6, len(ops))]])
    return snippets


_SNIPPETS = _numpy_snippets()
_DEEP = [b")" + b"\x85" * 200, b"(" * 40, b"]" + b"2a" * 50, b"}" + b"N" * 10, b"r\x00\x00\x00\x10"]


@st.composite
def _opcode_streams(draw: st.DrawFn) -> bytes:
    """A random sequence of pickle opcodes with arguments, mixed with runs of valid numpy
    pickles and hostile runs (deep nesting, huge memo index); usually ends with STOP."""
    parts = [draw(st.sampled_from([b"\x80\x02", b"\x80\x04", b"\x80\x05", b""]))]
    op = _OPCODE
    for _ in range(draw(st.integers(0, 40))):
        kind = draw(st.integers(0, 9))
        if kind < 6:
            parts.append(draw(op))
        elif kind < 9:
            parts.append(draw(st.sampled_from(_SNIPPETS)))
        else:
            parts.append(draw(st.sampled_from(_DEEP)))
    if draw(st.integers(0, 7)):
        parts.append(b".")
    return b"".join(parts)


def _opcode_runs() -> list[list[bytes]]:
    """Valid pickles of numpy values (protocols 2-5), each cut into its opcodes."""
    import pickletools

    runs = []
    for value in (
        good_motion(4),
        {"a": np.arange(12, dtype=np.float64).reshape(3, 4), "s": np.int32(7)},
        [np.zeros((2, 2), np.uint8), np.asfortranarray(np.ones((2, 3), np.float32))],
    ):
        for protocol in (2, 3, 4, 5):
            data = pickle.dumps(value, protocol=protocol)
            bounds = [pos for _, _, pos in pickletools.genops(data)] + [len(data)]
            runs.append([data[a:b] for a, b in zip(bounds, bounds[1:], strict=False)])
    return runs


_RUNS = _opcode_runs()


@st.composite
def _mutated_numpy_pickles(draw: st.DrawFn) -> bytes:
    """A valid pickle of numpy values, mutated at the opcode level: runs deleted, duplicated,
    swapped or replaced by random opcodes, and integers (shapes, lengths) changed."""
    chunks = list(draw(st.sampled_from(_RUNS)))
    for _ in range(draw(st.integers(1, 5))):
        if not chunks:
            break
        k = draw(st.integers(0, len(chunks) - 1))
        action = draw(st.sampled_from(["delete", "duplicate", "swap", "replace", "int"]))
        if action == "delete":
            del chunks[k]
        elif action == "duplicate":
            chunks.insert(k, chunks[k])
        elif action == "swap":
            j = draw(st.integers(0, len(chunks) - 1))
            chunks[k], chunks[j] = chunks[j], chunks[k]
        elif action == "replace":
            chunks[k] = draw(_OPCODE)
        else:
            chunks[k] = draw(
                st.sampled_from(
                    [b"K\x00", b"K\x01", b"M\xff\xff", b"J\xff\xff\xff\x7f", b"J\xff\xff\xff\xff"]
                )
            )
    return b"".join(chunks)


_SAFE_LEAVES = (type(None), bool, int, float, str, bytes, bytearray, np.generic, np.dtype)


def _assert_plain(value: Any, n_bytes: int) -> None:
    """What the unpickler returned holds only containers, plain values and numeric arrays that
    own their memory, built from at most twice the pickle's bytes."""
    todo, seen, built = [value], set(), 0
    while todo:
        item = todo.pop()
        if id(item) in seen:
            continue
        seen.add(id(item))
        if isinstance(item, (tuple, list, set, frozenset)):
            todo.extend(item)
        elif isinstance(item, dict):
            todo.extend(item.keys())
            todo.extend(item.values())
        elif isinstance(item, np.ndarray):
            assert item.dtype.kind in "biuf" and not item.dtype.hasobject, item.dtype
            assert item.flags.owndata and (item.flags.c_contiguous or item.flags.f_contiguous)
            built += item.nbytes
        else:
            assert isinstance(item, _SAFE_LEAVES), type(item)
    assert built <= 2 * n_bytes


def check_opcode_stream(data: bytes) -> None:
    """loads_restricted: plain values and checked arrays, or one InputError line naming the
    source; never another exception, never more than a second."""
    import time

    from dancedata.io.safe_pickle import loads_restricted

    began = time.monotonic()
    with within(5.0):
        try:
            value = loads_restricted(data, "fuzz.pkl")
        except InputError as exc:
            message = str(exc)
            assert "\n" not in message and message.startswith("fuzz.pkl: "), message
            assert "Hang" not in message, message  # the time limit fired inside the unpickler
            assert time.monotonic() - began < 1.0
            return
    assert time.monotonic() - began < 1.0
    _assert_plain(value, len(data))


# -- OpenPose JSON -----------------------------------------------------------------------------
def _openpose_doc(n_joints: int, people: int) -> bytes:
    doc = {
        "version": 1.3,
        "people": [
            {"person_id": [-1], "pose_keypoints_2d": [float(v % 97) for v in range(3 * n_joints)]}
            for _ in range(people)
        ],
    }
    import json

    return json.dumps(doc).encode()


@st.composite
def _openpose_folders(draw: st.DrawFn) -> list[bytes]:
    files = []
    for _ in range(draw(st.integers(1, 3))):
        data = bytearray(
            _openpose_doc(draw(st.sampled_from([25, 18, 17, 0, 1])), draw(st.integers(0, 3)))
        )
        for _ in range(draw(st.integers(0, 3))):
            pos = draw(st.integers(0, len(data)))
            if draw(st.booleans()) and pos < len(data):
                data[pos] = draw(st.integers(0, 255))
            else:
                data[pos:pos] = draw(st.sampled_from([b"NaN", b"1e999", b"\xff", b"[", b"}", b","]))
        files.append(bytes(data))
    return files


def check_openpose(files: list[bytes]) -> None:
    """read_openpose_folder: consistent ragged arrays, or one InputError line naming a file."""
    from dancedata.io.openpose import read_openpose_folder

    folder = _SCRATCH / "openpose"
    if folder.exists():
        for old in folder.iterdir():
            old.unlink()
    folder.mkdir(exist_ok=True)
    for k, data in enumerate(files):
        (folder / f"clip_{k:012d}_keypoints.json").write_bytes(data)
    with within(5.0):
        try:
            frames = read_openpose_folder(folder)
        except InputError as exc:
            _one_line(exc, folder)
            return
    assert frames.frame_offsets.shape == (frames.n_frames + 1,)
    assert frames.keypoints.shape[0] == frames.frame_offsets[-1] == frames.person_ids.shape[0]
    assert frames.keypoints.shape[1:] == (frames.skeleton.n_joints, 3)


# -- measures ----------------------------------------------------------------------------------
_ANY_FLOAT = st.one_of(
    st.floats(allow_nan=True, allow_infinity=True), st.floats(0.1, 400.0), st.floats(1.0, 240.0)
)


def check_measures(args: tuple[int, float, float, int, float]) -> None:
    """measure_bounds: a ValueError for impossible settings, else contiguous complete measures
    of floor/ceil(fpm) frames inside the sequence; fast."""
    from dancedata.compute.measures import frames_per_measure, measure_bounds

    n_frames, bpm, fps, beats, phase = args
    with within(2.0), warnings.catch_warnings():
        warnings.simplefilter("error")  # an overflowing cast is a bug, not a warning
        try:
            bounds = measure_bounds(n_frames, bpm, fps, beats, phase)
        except ValueError:
            return
    fpm = frames_per_measure(bpm, fps, beats)
    lengths = bounds[:, 1] - bounds[:, 0]
    assert set(lengths.tolist()) <= {math.floor(fpm), math.ceil(fpm)}
    assert np.all(bounds[:, 0] >= 0) and np.all(bounds[:, 1] <= max(n_frames, 0))
    assert np.all(bounds[1:, 0] == bounds[:-1, 1])


_MEASURE_ARGS = st.tuples(
    st.integers(-10, 200_000), _ANY_FLOAT, _ANY_FLOAT, st.integers(-2, 16), _ANY_FLOAT
)


# -- split lists -------------------------------------------------------------------------------
def check_name_list(data: bytes) -> None:
    """read_name_list: stripped, non-empty, unique names, or one InputError line."""
    from dancedata.io.aist import read_name_list

    path = _SCRATCH / "split.txt"
    path.write_bytes(data)
    try:
        names = read_name_list(path)
    except InputError as exc:
        _one_line(exc, path)
        return
    assert all(n and n == n.strip() for n in names) and len(names) == len(set(names))


TARGETS: dict[str, Target] = {
    t.name: t
    for t in (
        Target("bvh_valid", bvh_documents(), check_valid_doc, "generated valid BVH read exactly"),
        Target("bvh_mutated", mutated_bvh(), check_bvh_bytes, "damaged generated BVH"),
        Target("bvh_bytes", st.binary(max_size=2000), check_bvh_bytes, "random bytes as BVH"),
        Target("pickle", _PICKLES, check_pickle, "mutated motion pickles, opcode soup"),
        Target(
            "pickle_opcodes",
            st.one_of(_opcode_streams(), _mutated_numpy_pickles()),
            check_opcode_stream,
            "random pickle opcode streams and opcode-level mutations of numpy pickles",
        ),
        Target("openpose", _openpose_folders(), check_openpose, "mutated OpenPose JSON folders"),
        Target("measures", _MEASURE_ARGS, check_measures, "any numbers into measure_bounds"),
        Target("split_list", st.binary(max_size=300), check_name_list, "random split files"),
    )
}

__all__ = ["TARGETS", "Hang", "Target"]
