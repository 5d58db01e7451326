"""Generate the bad-input corpus: malformed pickles, BVH, audio, OpenPose JSON and split files.

    python tests/data/bad/make_corpus.py OUT      # writes OUT/... and OUT/cases.json

The corpus is generated (deterministically) rather than committed: the malicious pickles name an
absolute path they would create if ever executed, and the AIST++-shaped raw folders are a few MB.
The tests call :func:`make_corpus` into a temporary directory.

Every case names the file, the reader that must refuse it, and a regular expression the one-line
error must match after ``<path>: ``. ``cases.json`` lists them for humans and for ``fuzz/``.
Layout::

    OUT/pickle/<case>.pkl              refused by dancedata.io.aist.read_motion
    OUT/bvh/<case>.bvh                 refused by dancedata.io.bvh.read_bvh
    OUT/audio/<case>.<ext>             refused by dancedata.io.audio.audio_info
    OUT/openpose/<case>/*.json         refused by dancedata.io.openpose.read_openpose_folder
    OUT/aist_motions/                  AIST++ root: 3 good sequences + every bad pickle under an
                                       AIST++ name + music too short for its motion + split files
                                       naming sequences that do not exist
    OUT/aist_music/                    AIST++ root: 2 good sequences + sequences whose music is
                                       undecodable / header-only / wrongly named
    OUT/pwned-*                        must never exist: the malicious pickles would create them
"""

from __future__ import annotations

import json
import pickle
import shutil
import sys
from collections.abc import Callable
from dataclasses import asdict, dataclass
from pathlib import Path

import numpy as np

CORPUS_SEED = 7
N_FRAMES = 120


@dataclass(frozen=True)
class Case:
    """One bad input: where it is, which reader must refuse it and how the error must read."""

    kind: str  # pickle, bvh, audio, openpose, split
    name: str
    path: str  # relative to the corpus root
    expect: str  # regex matched against the error message after "<path>: "
    note: str = ""
    via: str = "reader"  # "reader": the io function refuses it; "ingest": dancedata ingest aist


# -- pickles -----------------------------------------------------------------------------------
def good_motion(n_frames: int = N_FRAMES, seed: int = CORPUS_SEED) -> dict:
    """A valid AIST++ motion dict: smpl_poses (N, 72), smpl_trans (N, 3) cm, scaling, loss."""
    rng = np.random.default_rng(seed)
    return {
        "smpl_poses": rng.normal(0.0, 0.3, (n_frames, 72)).astype(np.float32),
        "smpl_trans": (rng.normal(0.0, 5.0, (n_frames, 3)) + [0, 90, 0]).astype(np.float32),
        "smpl_scaling": np.array([93.0], dtype=np.float32),
        "smpl_loss": 1.25,
    }


def _reduce_payload(module: str, name: str, args: tuple) -> bytes:
    """Protocol-2 pickle bytes calling ``module.name(*args)``, built opcode by opcode (so the
    callable need not exist here, and nothing is imported to build it)."""
    body = pickle.dumps(args, protocol=2)[2:-1]  # the args tuple without PROTO and STOP
    return b"\x80\x02c" + f"{module}\n{name}\n".encode() + body + b"R."


class _Payload:
    """Pickles as a call of ``target(*args)``: what a malicious AIST++ mirror could ship."""

    def __init__(self, target: Callable, args: tuple) -> None:
        self.target, self.args = target, args

    def __reduce__(self) -> tuple:
        return (self.target, self.args)


# -- hostile pickles, written opcode by opcode (issue 11) --------------------------------------
# Each would crash, allocate gigabytes or store uninitialised memory through a pickle.Unpickler
# that admits numpy.dtype state or numpy.ndarray as a callable. They are assembled by hand so
# that building the corpus never runs them.
HOSTILE_FRAMES = 4_000_000  # frames a hostile file declares: 4e6 × 72 float64 = 2.3 GB
DEEP_NESTING = 200_000
HUGE_MEMO_INDEX = 2**28


def _op_str(text: str) -> bytes:
    """BINUNICODE: a str."""
    data = text.encode()
    return b"X" + len(data).to_bytes(4, "little") + data


def _op_int(value: int) -> bytes:
    """BININT (signed 32-bit) or LONG1 for anything larger."""
    if -(2**31) <= value < 2**31:
        return b"J" + value.to_bytes(4, "little", signed=True)
    data = value.to_bytes((value.bit_length() + 8) // 8, "little", signed=True)
    return b"\x8a" + bytes([len(data)]) + data


def _op_bytes(data: bytes) -> bytes:
    """BINBYTES (protocol 3)."""
    return b"B" + len(data).to_bytes(4, "little") + data


def _op_tuple(*items: bytes) -> bytes:
    return b"(" + b"".join(items) + b"t"


def _op_global(module: str, name: str) -> bytes:
    return b"c" + f"{module}\n{name}\n".encode()


def _op_dtype(typestr: str, state: bytes | None = None) -> bytes:
    """``numpy.dtype(typestr, False, True)``, then BUILD with ``state`` (numpy's own state for
    a plain little-endian dtype when None)."""
    if state is None:
        state = _op_tuple(_op_int(3), _op_str("<"), b"NNN", _op_int(-1), _op_int(-1), _op_int(0))
    return (
        _op_global("numpy", "dtype")
        + _op_tuple(_op_str(typestr), b"\x89\x88")
        + b"R"
        + state
        + b"b"
    )


def _op_shape(shape: tuple[int, ...]) -> bytes:
    return _op_tuple(*(_op_int(n) for n in shape))


def _op_reconstructed_array(shape: tuple[int, ...], dtype: bytes, data: bytes) -> bytes:
    """What numpy writes for an array: ``_reconstruct(ndarray, (0,), b"b")`` then BUILD with
    ``(1, shape, dtype, is_fortran=False, data)``."""
    head = _op_global("numpy.core.multiarray", "_reconstruct") + _op_tuple(
        _op_global("numpy", "ndarray"), _op_shape((0,)), _op_bytes(b"b")
    )
    state = _op_tuple(_op_int(1), _op_shape(shape), dtype, b"\x89", _op_bytes(data))
    return head + b"R" + state + b"b"


def _op_ndarray_call(shape: tuple[int, ...], dtype: bytes, *extra: bytes) -> bytes:
    """``numpy.ndarray(shape, dtype, *extra)`` called directly: uninitialised memory, or a view
    of ``buffer`` with any strides."""
    return _op_global("numpy", "ndarray") + _op_tuple(_op_shape(shape), dtype, *extra) + b"R"


def _op_plain(value: object) -> bytes:
    """``value`` as protocol-3 opcodes without PROTO and STOP (its memo puts dropped, so pieces
    can be joined)."""
    import pickletools

    return pickletools.optimize(pickle.dumps(value, protocol=3))[2:-1]


def _op_motion(
    replace: dict[str, bytes], good: dict | None = None, *, head: bytes = b"", tail: bytes = b""
) -> bytes:
    """A motion dict pickle whose values for the keys in ``replace`` are the given opcodes;
    ``head`` runs before the dict is built, ``tail`` inside it before SETITEMS."""
    good = good_motion() if good is None else good
    items = b"".join(
        _op_str(key) + (replace[key] if key in replace else _op_plain(value))
        for key, value in good.items()
    )
    return b"\x80\x04" + head + b"}(" + items + tail + b"u."


def hostile_pickles() -> list[tuple[str, bytes, str, str]]:
    """(name, bytes, expected error regex, note) for the memory-safety classes of issue 11."""
    n = HOSTILE_FRAMES
    f8 = _op_dtype("f8")
    # dtype flags NPY_ITEM_REFCOUNT | NPY_ITEM_HASOBJECT (0x1) without NPY_LIST_PICKLE (0x2):
    # numpy then reads the array's data from the bytes that follow, as PyObject pointers.
    object_flags = _op_tuple(_op_int(3), _op_str("|"), b"NNN", _op_int(8), _op_int(1), _op_int(0x1))
    deep = b")" + b"\x85" * DEEP_NESTING  # EMPTY_TUPLE then TUPLE1, 200,000 times
    return [
        (
            "evil_dtype_object_flags",
            _op_motion(
                {
                    "smpl_scaling": _op_reconstructed_array(
                        (1,), _op_dtype("O8", object_flags), b"A" * 8
                    )
                }
            ),
            r"unsafe pickle: refused dtype",
            "object dtype whose state drops the list-pickle flag: file bytes used as PyObject "
            "pointers (0x4141414141414141), SIGSEGV",
        ),
        (
            "evil_dtype_flags_on_float",
            _op_motion(
                {
                    "smpl_poses": _op_reconstructed_array(
                        (N_FRAMES, 72), _op_dtype("f8", object_flags), b"A" * 8 * N_FRAMES * 72
                    )
                }
            ),
            r"unsafe pickle: refused dtype",
            "float64 dtype whose state claims it holds objects: numpy internal errors",
        ),
        (
            "evil_ndarray_uninitialised",
            _op_motion({"smpl_poses": _op_ndarray_call((N_FRAMES, 72), _op_dtype("f4"))}),
            r"unsafe pickle: refused .*numpy\.ndarray",
            "numpy.ndarray(shape, dtype) called directly: uninitialised heap memory as poses",
        ),
        (
            "evil_ndarray_huge",
            b"\x80\x04}("
            + _op_str("smpl_poses")
            + _op_ndarray_call((n, 72), f8)
            + _op_str("smpl_trans")
            + _op_ndarray_call((n, 3), f8)
            + _op_str("smpl_scaling")
            + _op_plain(np.array([93.0], np.float32))
            + b"u.",
            r"unsafe pickle: refused .*numpy\.ndarray",
            f"a few hundred bytes declaring {n} frames of float64 (2.4 GB)",
        ),
        (
            "evil_zero_stride_view",
            _op_motion(
                {
                    key: _op_ndarray_call(
                        (n, width),
                        _op_dtype("f4"),
                        _op_bytes(b"\0" * 4),
                        _op_int(0),
                        _op_shape((0, 0)),
                    )
                    for key, width in (("smpl_poses", 72), ("smpl_trans", 3))
                }
            ),
            r"unsafe pickle: refused .*numpy\.ndarray",
            f"a zero-stride view of a 4-byte buffer as {n} frames",
        ),
        (
            "evil_huge_shape_few_bytes",
            _op_motion({"smpl_poses": _op_reconstructed_array((n, 72), f8, b"abc")}),
            r"unsafe pickle: refused array.*3 bytes",
            "the array state declares 2.3 GB and holds 3 bytes",
        ),
        (
            "evil_object_array",
            _op_motion({"smpl_poses": _op_reconstructed_array((1,), _op_dtype("O8"), b"")}),
            r"unsafe pickle: refused dtype 'O8'",
            "an object array would unpickle its items as Python objects",
        ),
        (
            "evil_structured_dtype",
            _op_motion(
                {
                    "smpl_poses": _op_reconstructed_array(
                        (1,),
                        _op_dtype(
                            "V8",
                            _op_tuple(
                                _op_int(3),
                                _op_str("|"),
                                b"N",
                                _op_tuple(_op_str("a")),
                                b"}" + _op_str("a") + _op_tuple(f8, _op_int(0)) + b"s",
                                _op_int(8),
                                _op_int(1),
                                _op_int(0x10),
                            ),
                        ),
                        b"\0" * 8,
                    )
                }
            ),
            r"unsafe pickle: refused dtype 'V8'",
            "a structured dtype with fields",
        ),
        (
            "evil_deep_nesting",
            _op_motion({}, tail=deep + _op_int(1)),
            r"unsafe pickle: refused .*nest",
            f"{DEEP_NESTING} nested tuples as a dict key (hashing them overflows the C stack)",
        ),
        (
            "evil_long_binput",
            _op_motion({}, head=b"N" + b"r" + HUGE_MEMO_INDEX.to_bytes(4, "little") + b"0"),
            r"unsafe pickle: refused memo index 268435456",
            "LONG_BINPUT 2**28: the C unpickler grows its memo table to gigabytes",
        ),
    ]


def converted_value_cases() -> list[tuple[str, bytes, str, str]]:
    """Motions whose values pass a check on what was read but overflow when converted to what
    is stored (float32, trans / scaling), and wrongly typed scalars (issue 11, items 2 and 8)."""
    good = good_motion()
    dump = lambda value: pickle.dumps(value, protocol=4)  # noqa: E731
    huge_poses = good["smpl_poses"].astype(np.float64)
    huge_poses[5, 7] = 1e300
    big_trans = good["smpl_trans"].copy()
    big_trans[9, 0] = 3e38  # finite float32 cm; / 0.5 overflows float32 metres
    return [
        (
            "scaling_1e-40",
            dump({**good, "smpl_scaling": np.array([1e-40], np.float32)}),
            r"smpl_scaling 1e-40 is outside the plausible range",
            "subnormal: trans / scaling overflows to Inf",
        ),
        (
            "poses_1e300_float64",
            dump({**good, "smpl_poses": huge_poses}),
            r"smpl_poses as stored \(float32 rad\) holds Inf \(first at frame 5\)",
            "finite float64, Inf once cast to float32",
        ),
        (
            "trans_overflows_after_scaling",
            dump({**good, "smpl_trans": big_trans, "smpl_scaling": np.array([0.5], np.float32)}),
            r"smpl_trans / smpl_scaling as stored \(float32 m\) holds Inf \(first at frame 9\)",
            "smpl_trans / smpl_scaling overflows float32",
        ),
        (
            "poses_out_of_range",
            dump({**good, "smpl_poses": good["smpl_poses"] * 1e6}),
            r"smpl_poses as stored .* outside the plausible range",
            "finite but millions of radians",
        ),
        (
            "scaling_string",
            dump({**good, "smpl_scaling": "93.0"}),
            r"smpl_scaling is str, expected one positive number",
            "a string where a number belongs",
        ),
        (
            "scaling_list",
            dump({**good, "smpl_scaling": [93.0, 1.0]}),
            r"smpl_scaling is list, expected one positive number",
            "",
        ),
    ]


def _pickle_cases(root: Path) -> list[tuple[str, bytes, str, str]]:
    """(name, bytes, expected error regex, note) for every bad motion pickle."""
    import os
    import subprocess

    good = good_motion()
    dump = lambda value: pickle.dumps(value, protocol=4)  # noqa: E731
    good_bytes = dump(good)

    def variant(**changes: object) -> bytes:
        value = {k: v for k, v in good.items() if k not in changes or changes[k] is not None}
        value.update({k: v for k, v in changes.items() if v is not None})
        return dump(value)

    def without(key: str) -> bytes:
        return dump({k: v for k, v in good.items() if k != key})

    nan_poses = good["smpl_poses"].copy()
    nan_poses[7, 3] = np.nan
    inf_trans = good["smpl_trans"].copy()
    inf_trans[11, 1] = np.inf
    pwned = lambda case: str(root / f"pwned-{case}")  # noqa: E731
    unsafe = r"unsafe pickle: refused (to load global|numpy _reconstruct)"
    return [
        ("truncated", good_bytes[: len(good_bytes) // 2], r"unreadable pickle", "cut in half"),
        ("empty", b"", r"unreadable pickle", "0 bytes"),
        ("not_a_pickle", b"smpl_poses,smpl_trans\n1,2\n", r"unreadable pickle", "CSV text"),
        ("not_a_dict", dump([good["smpl_poses"]]), r"expected a dict of arrays, found list", ""),
        ("missing_poses", without("smpl_poses"), r"missing key 'smpl_poses'", "wrong keys"),
        ("missing_trans", without("smpl_trans"), r"missing key 'smpl_trans'", "wrong keys"),
        ("missing_scaling", without("smpl_scaling"), r"missing key 'smpl_scaling'", ""),
        (
            "renamed_keys",
            dump({"poses": good["smpl_poses"], "trans": good["smpl_trans"]}),
            r"missing key 'smpl_poses'",
            "AMASS-style keys",
        ),
        (
            "poses_69",
            variant(smpl_poses=good["smpl_poses"][:, :69]),
            r"smpl_poses has shape \(120, 69\), expected \(N, 72\)",
            "wrong shape",
        ),
        (
            "poses_3d",
            variant(smpl_poses=good["smpl_poses"].reshape(N_FRAMES, 24, 3)),
            r"smpl_poses has shape \(120, 24, 3\), expected \(N, 72\)",
            "wrong rank",
        ),
        (
            "trans_transposed",
            variant(smpl_trans=good["smpl_trans"].T.copy()),
            r"smpl_trans has shape \(3, 120\), expected \(N, 3\)",
            "",
        ),
        (
            "poses_strings",
            variant(smpl_poses=good["smpl_poses"].astype(str)),
            r"unsafe pickle: refused dtype 'U\d+': only bool, integer and float arrays",
            "wrong dtype: the unpickler builds only bool/int/float arrays",
        ),
        (
            "poses_bool",
            variant(smpl_poses=good["smpl_poses"] > 0),
            r"smpl_poses has dtype bool, expected numbers",
            "wrong dtype",
        ),
        (
            "poses_list",
            variant(smpl_poses=good["smpl_poses"].tolist()),
            r"smpl_poses is list, expected a numpy array",
            "",
        ),
        (
            "nan_poses",
            variant(smpl_poses=nan_poses),
            r"smpl_poses holds NaN or Inf \(first at frame 7\)",
            "",
        ),
        (
            "inf_trans",
            variant(smpl_trans=inf_trans),
            r"smpl_trans holds NaN or Inf \(first at frame 11\)",
            "",
        ),
        (
            "zero_frames",
            variant(smpl_poses=good["smpl_poses"][:0], smpl_trans=good["smpl_trans"][:0]),
            r"zero frames",
            "",
        ),
        (
            "frame_mismatch",
            variant(smpl_trans=good["smpl_trans"][:90]),
            r"smpl_poses has 120 frames but smpl_trans has 90",
            "",
        ),
        (
            "zero_scaling",
            variant(smpl_scaling=np.array([0.0], np.float32)),
            r"smpl_scaling must be one positive number, found 0",
            "division by zero otherwise",
        ),
        (
            "evil_os_system",
            dump(_Payload(os.system, (f"touch {pwned('evil_os_system')}",))),
            unsafe,
            "would run a shell command",
        ),
        (
            "evil_nested_in_dict",
            dump({**good, "smpl_loss": _Payload(os.system, (f"touch {pwned('nested')}",))}),
            unsafe,
            "payload hidden in an otherwise valid motion",
        ),
        (
            "evil_builtins_exec",
            _reduce_payload("builtins", "exec", (f"open({pwned('exec')!r}, 'w').close()",)),
            unsafe,
            "",
        ),
        (
            "evil_builtins_open",
            _reduce_payload("builtins", "open", (pwned("open"), "w")),
            unsafe,
            "",
        ),
        (
            "evil_subprocess",
            dump(_Payload(subprocess.call, (["touch", pwned("subprocess")],))),
            unsafe,
            "",
        ),
        (
            "evil_protocol0_inst",
            f"(S'touch {pwned('inst')}'\nios\nsystem\n.".encode(),
            unsafe,
            "protocol-0 INST opcode",
        ),
        (
            "evil_numpy_gadget",
            _reduce_payload(
                "numpy.testing._private.utils", "runstring", (f"open({pwned('np')!r}, 'w')", {})
            ),
            unsafe,
            "a numpy function that executes a string",
        ),
        (
            "evil_memory_bomb",
            _reduce_payload(
                "numpy._core.multiarray", "_reconstruct", (np.ndarray, (10**12,), b"b")
            ),
            unsafe,
            "asks numpy for 1 TB",
        ),
        (
            "unknown_codec",
            _reduce_payload("_codecs", "encode", ("abc", "atin1")),
            r"unsafe pickle: refused _codecs\.encode\('abc', 'atin1'\): only \(str, 'latin1'\)",
            "found by fuzz/: an allowed function with a bad argument",
        ),
        (
            "persistent_id",
            b"\x80\x04P",
            r"unsafe pickle: refused persistent id \(PERSID\)",
            "found by fuzz/: pickle's message spans two lines",
        ),
        (
            "lying_length",
            b"\x80\x04\x95\x10\x00\x00\x00\x00\x00\x00\x00B\xff\xff\xff\x7fabc",
            r"unreadable pickle",
            "BINBYTES claims 2 GB, holds 3 bytes",
        ),
        *hostile_pickles(),
        *converted_value_cases(),
    ]


# -- BVH ---------------------------------------------------------------------------------------
BVH_GOOD = """HIERARCHY
ROOT Hips
{
  OFFSET 0 0 0
  CHANNELS 6 Xposition Yposition Zposition Zrotation Xrotation Yrotation
  JOINT Spine
  {
    OFFSET 0 10 0
    CHANNELS 3 Zrotation Xrotation Yrotation
    End Site
    {
      OFFSET 0 5 0
    }
  }
}
MOTION
Frames: 3
Frame Time: 0.0083333
0 90 0 1 2 3 4 5 6
0.5 90.5 0 1 2 3 4 5 6
1 91 0 1 2 3 4 5 6
"""


def _bvh_cases() -> list[tuple[str, bytes, str, str]]:
    g = BVH_GOOD
    motion_at = g.index("MOTION")
    lines = g.split("\n")
    header, first_row = "\n".join(lines[:-4]), lines[-4]

    def swap(old: str, new: str) -> bytes:
        assert old in g, old
        return g.replace(old, new, 1).encode()

    line_re = r"line \d+: "
    return [
        ("empty", b"", r"empty file", ""),
        ("binary", bytes(range(256)) * 4, r"no HIERARCHY found|line \d+", "random bytes"),
        (
            "missing_hierarchy",
            g[g.index("ROOT") :].encode(),
            r"no HIERARCHY found|line 1: expected HIERARCHY",
            "",
        ),
        ("missing_motion", g[:motion_at].encode(), line_re + r".*without a MOTION section", ""),
        (
            "channel_count_short",
            swap("0.5 90.5 0 1 2 3 4 5 6", "0.5 90.5 0 1 2 3 4 5"),
            line_re + r".*8 values.*9|line \d+: .*channel",
            "a motion line with one value too few",
        ),
        (
            "channel_count_long",
            swap("0.5 90.5 0 1 2 3 4 5 6", "0.5 90.5 0 1 2 3 4 5 6 7"),
            line_re + r".*10 values.*9|line \d+: .*channel",
            "one value too many",
        ),
        (
            "truncated_motion",
            (header + "\n" + first_row + "\n").encode(),
            line_re + r".*(frame|truncated)",
            "Frames: 3 but one line present",
        ),
        (
            "truncated_mid_line",
            g[: g.rindex("4 5 6")].encode(),
            line_re,
            "file cut inside the last line",
        ),
        ("glued_numbers", swap("0.5 90.5 0", "0.5 90.5-7.5"), line_re + r".*0\.5-7\.5|glued", ""),
        ("word_in_motion", swap("0.5 90.5 0", "0.5 ninety 0"), line_re + r".*ninety", ""),
        ("nan_in_motion", swap("0.5 90.5 0", "0.5 nan 0"), line_re, "non-finite value"),
        (
            "inf_in_motion",
            swap("0.5 90.5 0", "0.5 1e999 0"),
            line_re,
            "overflows to infinity",
        ),
        ("frames_missing", swap("Frames: 3\n", ""), line_re + r".*Frames", ""),
        ("frames_negative", swap("Frames: 3", "Frames: -3"), line_re, ""),
        ("frames_word", swap("Frames: 3", "Frames: three"), line_re + r".*three", ""),
        ("frame_time_zero", swap("Frame Time: 0.0083333", "Frame Time: 0"), line_re, ""),
        ("frame_time_missing", swap("Frame Time: 0.0083333\n", ""), line_re, ""),
        (
            "unbalanced_open_brace",
            swap("      OFFSET 0 5 0\n    }\n", "      OFFSET 0 5 0\n"),
            line_re,
            "a missing closing brace",
        ),
        ("extra_close_brace", swap("}\nMOTION", "}\n}\nMOTION"), line_re, ""),
        (
            "unknown_channel",
            swap(
                "Zrotation Xrotation Yrotation\n    End", "Zrotation Wrotation Yrotation\n    End"
            ),
            line_re + r".*Wrotation",
            "",
        ),
        (
            "channel_count_word",
            swap("CHANNELS 3 Zrotation Xrotation Yrotation", "CHANNELS 3 Zrotation Xrotation"),
            line_re,
            "declares 3 channels, names 2",
        ),
        ("channels_not_number", swap("CHANNELS 3", "CHANNELS three"), line_re, ""),
        ("offset_short", swap("OFFSET 0 10 0", "OFFSET 0 10"), line_re + r".*OFFSET", ""),
        ("offset_word", swap("OFFSET 0 10 0", "OFFSET 0 ten 0"), line_re, ""),
        ("joint_without_name", swap("JOINT Spine", "JOINT"), line_re, ""),
        ("joint_without_brace", swap("JOINT Spine\n  {", "JOINT Spine\n"), line_re, ""),
        ("root_missing", swap("ROOT Hips", "Hips"), line_re + r"|no HIERARCHY", ""),
        ("two_hierarchies", (g[:motion_at] + g).encode(), line_re, "HIERARCHY twice"),
        (
            "stray_keyword",
            swap("  OFFSET 0 0 0\n", "  OFFSET 0 0 0\n  ROTATION 1 2 3\n"),
            line_re + r".*ROTATION",
            "",
        ),
    ]


# -- audio -------------------------------------------------------------------------------------
def _wav_bytes(seconds: float, sr: int = 24000, silent: bool = False) -> bytes:
    import io

    import soundfile as sf

    n = int(round(seconds * sr))
    rng = np.random.default_rng(CORPUS_SEED)
    y = np.zeros(n, np.float32) if silent else (0.2 * rng.standard_normal(n)).astype(np.float32)
    buf = io.BytesIO()
    sf.write(buf, y, sr, format="WAV", subtype="PCM_16")
    return buf.getvalue()


def _float_wav_bytes(bad_value: float, sr: int = 24000) -> bytes:
    """1 s of a quiet tone as 32-bit float WAV with ``bad_value`` at sample 1000 (issue 11.8)."""
    import io

    import soundfile as sf

    y = (0.1 * np.sin(np.arange(sr) * 2 * np.pi * 440 / sr)).astype(np.float32)
    y[1000] = bad_value
    buf = io.BytesIO()
    sf.write(buf, y, sr, format="WAV", subtype="FLOAT")
    return buf.getvalue()


def _audio_cases() -> list[tuple[str, bytes, str, str]]:
    wav = _wav_bytes(1.0)
    return [
        # issue 11.8: bad samples are named, not reported as "not readable or truncated"
        (
            "nan_sample.wav",
            _float_wav_bytes(np.nan),
            r"non-finite audio sample \(nan\) at sample "
            r"1000",
            "NaN in a float WAV",
        ),
        ("inf_sample.wav", _float_wav_bytes(np.inf), r"non-finite audio sample \(inf\)", "+Inf"),
        (
            "huge_sample.wav",
            _float_wav_bytes(1e30),
            r"out-of-range audio sample \(1e\+30\)",
            "1e30 in a float WAV (its power spectrum overflows float32)",
        ),
        (
            "text_named_wav.wav",
            b"RIFX" + b"not audio at all " * 40,
            r"cannot decode audio: .*"
            r"whatever the extension",
            "content no decoder reads, named .wav",
        ),
        ("header_only.wav", wav[:44], r"cannot decode audio|holds no samples", "RIFF header only"),
        ("torn_header.wav", wav[:20], r"cannot decode audio", "cut inside the header"),
        ("text_as.wav", b"this is not audio\n" * 20, r"cannot decode audio", "wrong content"),
        ("empty.wav", b"", r"cannot decode audio|holds no samples", "0 bytes"),
    ]


# -- OpenPose ----------------------------------------------------------------------------------
def _openpose_person(n_joints: int) -> dict:
    values = []
    for j in range(n_joints):
        values += [100.0 + j, 200.0 + j, 0.9]
    return {"person_id": [-1], "pose_keypoints_2d": values}


def _openpose_doc(n_joints: int = 25) -> dict:
    return {"version": 1.3, "people": [_openpose_person(n_joints)]}


def _openpose_cases() -> list[tuple[str, dict[str, bytes], str, str]]:
    ok = json.dumps(_openpose_doc()).encode()
    name = "clip_{:012d}_keypoints.json".format
    bad_values = _openpose_doc()
    bad_values["people"][0]["pose_keypoints_2d"][4] = "x"
    short = _openpose_doc()
    short["people"][0]["pose_keypoints_2d"] = short["people"][0]["pose_keypoints_2d"][:-1]
    return [
        (
            "joints_20",
            {name(0): json.dumps(_openpose_doc(20)).encode()},
            r"60 pose values: expected 75 \(BODY_25, 25 joints\) or 54",
            "neither BODY_25 nor COCO",
        ),
        (
            "joints_not_multiple_of_3",
            {name(0): ok, name(1): json.dumps(short).encode()},
            r"person 0 has 74 pose values, expected 75",
            "",
        ),
        (
            "mixed_models",
            {name(0): ok, name(1): ok, name(2): json.dumps(_openpose_doc(18)).encode()},
            r"person 0 has 54 pose values, expected 75",
            "a COCO frame among BODY_25 frames",
        ),
        (
            "non_utf8",
            {name(0): ok, name(1): ok[:30] + b"\xff\xfe" + ok[30:]},
            r"not UTF-8 text \(byte 30\)",
            "",
        ),
        (
            "latin1",
            {name(0): '{"version": "1.3 é", "people": []}'.encode("latin-1")},
            r"not UTF-8 text",
            "",
        ),
        ("truncated_json", {name(0): ok, name(1): ok[: len(ok) // 2]}, r"not valid JSON", ""),
        ("top_level_list", {name(0): b"[1, 2, 3]"}, r"top level is not a JSON object", ""),
        ("no_people", {name(0): b'{"version": 1.3}'}, r"no 'people' list", ""),
        ("values_not_numbers", {name(0): json.dumps(bad_values).encode()}, r"not all numbers", ""),
        ("empty_folder", {}, r"no \*_keypoints\.json files", ""),
    ]


# -- AIST++-shaped raw folders -----------------------------------------------------------------
def _aist_names(raw: Path) -> list[str]:
    return sorted(p.stem for p in (raw / "motions").glob("*.pkl"))


def _renamed(seq_id: str, dancer: int | None = None, music: str | None = None) -> str:
    """Another valid AIST++ name: same genre, another dancer and/or music id."""
    parts = seq_id.split("_")  # g.. s.. c.. d.. m.. ch..
    if dancer is not None:
        parts[3] = f"d{dancer:02d}"
    if music is not None:
        parts[4] = music
    return "_".join(parts)


def _music_id(seq_id: str) -> str:
    return seq_id.split("_")[4]


def make_aist_motions(out: Path, pickle_cases: list[tuple[str, bytes, str, str]]) -> list[Case]:
    """3 good sequences, every bad pickle under a valid AIST++ name (sharing a good sequence's
    music), one good motion whose music is too short, and split files naming missing sequences."""
    from dancedata.synth.aist import synth_aist

    synth_aist(out, n_sequences=3, seed=CORPUS_SEED)
    good = _aist_names(out)
    cases: list[Case] = []
    for k, (name, data, expect, note) in enumerate(pickle_cases):
        seq_id = _renamed(good[k % len(good)], dancer=10 + k % 20)
        seq_id = seq_id.replace("_ch0", f"_ch{(k // 20) + 2}")  # unique even past 20 cases
        rel = f"motions/{seq_id}.pkl"
        (out / rel).write_bytes(data)
        cases.append(Case("pickle", name, f"{out.name}/{rel}", expect, note, via="ingest"))
    # Music too short for its motion: a fresh music id, 1 s of audio, a 120-frame (2 s) motion.
    genre = good[0][1:3]
    short_music = f"m{genre}5" if _music_id(good[0]) != f"m{genre}5" else f"m{genre}4"
    seq_id = _renamed(good[0], dancer=30, music=short_music)
    (out / "motions" / f"{seq_id}.pkl").write_bytes(pickle.dumps(good_motion(), protocol=4))
    (out / "wav" / f"{short_music}.wav").write_bytes(_wav_bytes(1.0))
    cases.append(
        Case(
            "audio",
            "too_short_for_motion",
            f"{out.name}/motions/{seq_id}.pkl",
            rf"music {short_music} gives \d+ feature frames .* but the motion has 120 frames",
            "1 s of music under a 2 s motion",
            via="ingest",
        )
    )
    # Split files naming sequences that do not exist.
    ghosts = ["gBR_sBM_cAll_d99_mBR0_ch99", "not_even_a_name", "  gPO_sFM_cAll_d98_mPO1_ch98  "]
    for split in ("train", "val"):
        path = out / "splits" / f"crossmodal_{split}.txt"
        text = path.read_text(encoding="utf-8") if path.exists() else ""
        path.write_text(text + "\n" + "\n".join(ghosts) + "\n\n", encoding="utf-8")
    cases.append(
        Case(
            "split",
            "names_not_in_store",
            f"{out.name}/splits/crossmodal_train.txt",
            r"missing_from_store",
            "3 names per split file with no motion: counted as missing_from_store, no rows",
            via="ingest",
        )
    )
    return cases


def make_aist_music(out: Path) -> list[Case]:
    """2 good sequences plus sequences whose music cannot be decoded, or is named wrongly."""
    from dancedata.synth.aist import synth_aist

    synth_aist(out, n_sequences=2, seed=CORPUS_SEED + 1)
    good = _aist_names(out)
    genre = good[0][1:3]
    used = {_music_id(s) for s in good}
    free = [f"m{genre}{k}" for k in range(6) if f"m{genre}{k}" not in used]
    cases = []
    wav = _wav_bytes(3.0)
    bad_music = [
        ("undecodable", b"not audio at all\n" * 64, ".wav", r"cannot decode audio"),
        ("header_only", wav[:44], ".wav", r"cannot decode audio|holds no samples"),
    ]
    for k, (name, data, ext, expect) in enumerate(bad_music):
        music = free[k]
        seq_id = _renamed(good[0], dancer=40 + k, music=music)
        (out / "motions" / f"{seq_id}.pkl").write_bytes(pickle.dumps(good_motion(), protocol=4))
        (out / "wav" / f"{music}{ext}").write_bytes(data)
        cases.append(
            Case("audio", name, f"{out.name}/wav/{music}{ext}", expect, seq_id, via="ingest")
        )
    return cases


# -- driver ------------------------------------------------------------------------------------
def make_corpus(out: str | Path) -> list[Case]:
    """Write the whole corpus under ``out`` (replacing it) and return its cases."""
    out = Path(out).resolve()
    if out.exists():
        shutil.rmtree(out)
    out.mkdir(parents=True)
    cases: list[Case] = []
    pickle_cases = _pickle_cases(out)
    for kind, folder, items in (
        ("pickle", "pickle", [(f"{n}.pkl", d, e, note) for n, d, e, note in pickle_cases]),
        ("bvh", "bvh", [(f"{n}.bvh", d, e, note) for n, d, e, note in _bvh_cases()]),
        ("audio", "audio", _audio_cases()),
    ):
        (out / folder).mkdir()
        for filename, data, expect, note in items:
            (out / folder / filename).write_bytes(data)
            cases.append(Case(kind, Path(filename).stem, f"{folder}/{filename}", expect, note))
    (out / "openpose").mkdir()
    for name, files, expect, note in _openpose_cases():
        folder = out / "openpose" / name
        folder.mkdir()
        for filename, data in files.items():
            (folder / filename).write_bytes(data)
        cases.append(Case("openpose", name, f"openpose/{name}", expect, note))
    cases += make_aist_motions(out / "aist_motions", pickle_cases)
    cases += make_aist_music(out / "aist_music")
    (out / "cases.json").write_text(
        json.dumps([asdict(c) for c in cases], indent=1) + "\n", encoding="utf-8"
    )
    return cases


def summary(cases: list[Case]) -> dict[str, int]:
    """Number of cases per kind and route, e.g. ``{"pickle/reader": 28, ...}``."""
    counts: dict[str, int] = {}
    for case in cases:
        key = f"{case.kind}/{case.via}"
        counts[key] = counts.get(key, 0) + 1
    return counts


if __name__ == "__main__":
    if len(sys.argv) != 2:
        sys.exit("usage: python tests/data/bad/make_corpus.py OUT")
    made = make_corpus(sys.argv[1])
    print(f"{len(made)} cases in {sys.argv[1]}: {summary(made)}")
