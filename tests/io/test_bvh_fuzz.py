"""Fuzzing the BVH reader: on any input it returns a clip or raises one InputError whose single
line names the line number (or says plainly that the file is empty / not BVH). It never hangs
and never leaks another exception type."""

from __future__ import annotations

import re
import time

import numpy as np
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from dancedata.errors import InputError
from dancedata.io.bvh import parse_bvh

BASE = b"""HIERARCHY
ROOT Hips
{
  OFFSET 0 0 0
  CHANNELS 6 Xposition Yposition Zposition Zrotation Xrotation Yrotation
  JOINT mixamorig:Spine
  {
    OFFSET 0 10 0
    CHANNELS 3 Zrotation Yrotation Xrotation
    End Site
    {
      OFFSET 0 5 0
    }
  }
  JOINT Leg.L
  {
    OFFSET 3 -10 0
    CHANNELS 6 Xposition Yposition Zposition Xrotation Yrotation Zrotation
  }
}
MOTION
Frames: 3
Frame Time: 0.0083333
0 90 0 1 2 3 4 5 6 3 -10 0 1 2 3
0.5 90.5 0 1 2 3 4 5 6 3 -10 0 1 2 3
1 91 0 1 2 3 4 5 6 3 -10 0 1 2 3
"""

_LINE_LESS = ("empty file", "no HIERARCHY found")
_PIECES = [
    b" ", b"\t", b"\n", b"\r\n", b"{", b"}", b"-", b"+", b".", b"e", b"0", b"7", b":", b"x",
    b"JOINT", b"End Site", b"OFFSET", b"CHANNELS", b"ROOT", b"MOTION", b"Frames:", b"nan",
    b"\x00", b"\xff", b"Frame Time:",
]  # fmt: skip


def _check(data: bytes) -> None:
    start = time.perf_counter()
    try:
        clip = parse_bvh(data, path="fuzz.bvh")
    except InputError as exc:
        message = str(exc)
        assert "\n" not in message, message
        assert message.startswith("fuzz.bvh: ")
        assert re.search(r"line \d+: \S", message) or any(s in message for s in _LINE_LESS), message
    else:
        assert clip.values.shape == (clip.n_frames, clip.skeleton.n_channels)
        assert np.isfinite(clip.values).all()
    assert time.perf_counter() - start < 2.0


@st.composite
def _mutated(draw) -> bytes:
    data = bytearray(BASE)
    for _ in range(draw(st.integers(1, 4))):
        kind = draw(st.sampled_from(["delete", "insert", "replace", "dup_line", "truncate"]))
        pos = draw(st.integers(0, len(data)))
        if kind == "delete":
            del data[pos : pos + draw(st.integers(1, 12))]
        elif kind == "insert":
            data[pos:pos] = draw(st.sampled_from(_PIECES))
        elif kind == "replace" and pos < len(data):
            data[pos] = draw(st.integers(0, 255))
        elif kind == "dup_line":
            lines = bytes(data).split(b"\n")
            k = draw(st.integers(0, len(lines) - 1))
            lines.insert(k, lines[k])
            data = bytearray(b"\n".join(lines))
        else:
            del data[pos:]
    return bytes(data)


@settings(max_examples=300, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(_mutated())
def test_mutated_files_give_a_clip_or_one_clear_error(data):
    _check(data)


@settings(max_examples=100, deadline=None)
@given(st.binary(max_size=400))
def test_random_bytes_never_crash(data):
    _check(data)


@settings(max_examples=50, deadline=None)
@given(st.lists(st.sampled_from(_PIECES), max_size=60))
def test_token_soup_never_crashes(pieces):
    _check(b"HIERARCHY\nROOT A\n{\n" + b" ".join(pieces))


def test_deep_nesting_does_not_hit_the_recursion_limit():
    depth = 5000
    text = "HIERARCHY\nROOT J0\n{\nOFFSET 0 0 0\nCHANNELS 1 Xrotation\n"
    for i in range(1, depth):
        text += f"JOINT J{i}\n{{\nOFFSET 0 1 0\nCHANNELS 1 Xrotation\n"
    text += "}\n" * depth + f"MOTION\nFrames: 1\nFrame Time: 0.1\n{' '.join(['0'] * depth)}\n"
    clip = parse_bvh(text)
    assert clip.skeleton.n_joints == depth
    assert clip.skeleton.parents[-1] == depth - 2


_DATA_START = BASE.index(b"Frames:")


@st.composite
def _mutated_motion(draw) -> bytes:
    """Mutations inside the MOTION block, where the fast numeric path runs."""
    data = bytearray(BASE)
    for _ in range(draw(st.integers(1, 3))):
        pos = draw(st.integers(_DATA_START, len(data)))
        piece = draw(st.sampled_from([*_PIECES, b"1e999", b"-.5", b"1.", b"+3", b"0.0-7.5"]))
        if draw(st.booleans()):
            data[pos:pos] = piece
        else:
            del data[pos : pos + draw(st.integers(1, 6))]
    return bytes(data)


@settings(max_examples=200, deadline=None)
@given(_mutated_motion())
def test_mutated_motion_blocks_give_a_clip_or_one_clear_error(data):
    _check(data)
