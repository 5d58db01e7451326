"""Structure-aware property tests of the BVH reader, complementing tests/io/test_bvh_fuzz.py (which
mutates one fixed file): here the *valid* files are generated from random rigs and must be read
exactly, their damaged versions must give a clip or one InputError naming a real line, and size
must cost linear time (no hang on long lines, many frames or deep braces)."""

from __future__ import annotations

import re
import time

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings

from dancedata.errors import InputError
from dancedata.io.bvh import format_bvh, parse_bvh
from tests.fault_strategies import BvhDoc, bvh_documents, mutated_bvh, within

_LINE = re.compile(r"^fuzz\.bvh: line (\d+): \S")
_LINE_LESS = ("fuzz.bvh: empty file", "fuzz.bvh: no HIERARCHY found")


def check_bvh_bytes(data: bytes) -> None:
    """The reader's contract on any bytes: a consistent clip, or one InputError line that names
    a line of the file (or says it is empty / not BVH); within 2 s."""
    with within(2.0):
        try:
            clip = parse_bvh(data, path="fuzz.bvh")
        except InputError as exc:
            message = str(exc)
            assert "\n" not in message, message
            match = _LINE.match(message)
            if match is None:
                assert message.startswith(_LINE_LESS), message
            else:
                n_lines = data.count(b"\n") + data.count(b"\r") + 1
                assert 1 <= int(match.group(1)) <= n_lines + 1, (message, n_lines)
            return
    assert clip.values.shape == (clip.n_frames, clip.skeleton.n_channels)
    assert np.isfinite(clip.values).all()
    assert clip.frame_time_s > 0
    assert all(0 <= p < j for j, p in enumerate(clip.skeleton.parents) if j)


def check_valid_doc(doc: BvhDoc) -> None:
    """A generated valid file is read exactly as written."""
    with within(2.0):
        clip = parse_bvh(doc.text, path="gen.bvh")
    sk = clip.skeleton
    assert sk.names == doc.names
    assert sk.parents == doc.parents
    assert sk.channels == doc.channels
    np.testing.assert_array_equal(sk.offsets, doc.offsets)
    assert tuple(len(e) for e in sk.end_sites) == doc.end_sites
    assert clip.values.shape == doc.values.shape
    np.testing.assert_array_equal(clip.values, doc.values)
    assert clip.frame_time_s == doc.frame_time


@pytest.mark.slow
@settings(max_examples=80, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(bvh_documents())
def test_generated_valid_files_are_read_exactly(doc):
    check_valid_doc(doc)


@settings(max_examples=60, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(bvh_documents())
def test_what_the_writer_writes_reads_back_the_same(doc):
    clip = parse_bvh(doc.text)
    again = parse_bvh(format_bvh(clip, precision=9))  # fixed decimals: within 5e-10
    assert again.skeleton.names == clip.skeleton.names
    assert again.skeleton.same_hierarchy(clip.skeleton, atol=1e-9)
    np.testing.assert_allclose(again.values, clip.values, rtol=0, atol=1e-9)


@pytest.mark.slow
@settings(max_examples=120, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(mutated_bvh())
def test_damaged_generated_files_give_a_clip_or_one_error_naming_a_real_line(data):
    check_bvh_bytes(data)


@settings(max_examples=25, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(bvh_documents(max_frames=6))
def test_every_truncation_of_a_valid_file_is_handled(doc):
    data = doc.text.encode()
    for cut in range(0, len(data), max(1, len(data) // 60)):
        check_bvh_bytes(data[:cut])


def _rig(n_channels_per_joint: int, n_joints: int) -> str:
    chans = " ".join(["Xrotation", "Yrotation", "Zrotation"][:n_channels_per_joint])
    text = f"HIERARCHY\nROOT J0\n{{\nOFFSET 0 0 0\nCHANNELS {n_channels_per_joint} {chans}\n"
    for j in range(1, n_joints):
        text += f"JOINT J{j}\n{{\nOFFSET 0 1 0\nCHANNELS {n_channels_per_joint} {chans}\n}}\n"
    return text + "}\n"


def test_reading_time_grows_linearly_with_the_number_of_frames():
    rig = _rig(3, 20)
    row = " ".join(["12.5"] * 60)

    def seconds(frames: int) -> float:
        text = rig + f"MOTION\nFrames: {frames}\nFrame Time: 0.01\n" + (row + "\n") * frames
        start = time.perf_counter()
        assert parse_bvh(text).n_frames == frames
        return time.perf_counter() - start

    small, large = seconds(2000), seconds(40000)
    assert large < 2.0
    assert large < 20 * max(small, 0.005) * 3  # 20x the frames: at most ~60x the time


def test_pathological_sizes_fail_fast():
    rig = _rig(3, 1)
    head = rig + "MOTION\nFrames: 1\nFrame Time: 0.01\n"
    cases = [
        head + "1" * 2_000_000 + "\n",  # one enormous number
        head + " ".join(["1"] * 500_000) + "\n",  # far too many values on one line
        "HIERARCHY\nROOT A\n" + "{\n" * 200_000,  # braces without end
        "HIERARCHY\n" + "ROOT A\n" * 100_000,
        head + "1 2 3\n" * 300_000,  # far more frames than declared
    ]
    for text in cases:
        start = time.perf_counter()
        check_bvh_bytes(text.encode())
        assert time.perf_counter() - start < 2.0
