"""BVH reader: the five real files as docs/FORMATS.md ("Real test files") describes them, the
edge cases of docs/FORMATS.md ("BVH edge cases"), and malformed input rejected with the line
number."""

from __future__ import annotations

import re
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from dancedata.errors import InputError
from dancedata.io import bvh
from dancedata.io.bvh import (
    euler_degrees,
    local_translations,
    parse_bvh,
    read_bvh,
    root_translation,
)
from dancedata.ops.bvh_clip import world_positions

# file, joints, channels, frames, frame time (as printed), nominal fps, End Sites, orders
REAL_FILES = [
    ("01_01.bvh", 31, 96, 2752, 0.0083333, 120.0, 7, {"ZYX"}),
    ("AV_8Walk_Meredith_HVHA_Rep1.bvh", 23, 72, 1064, 0.008333, 120.0, 7, {"XYZ"}),
    ("test_freebvh.bvh", 55, 168, 69, 0.0333333, 30.0, 15, {"ZYX"}),
    ("test_mocapbank.bvh", 19, 60, 455, 0.033333, 30.0, 5, {"ZXY"}),
    ("freya_edit.bvh", 59, 354, 733, 0.008, 125.0, 13, {"YXZ"}),
]


def _data_lines(path: Path) -> np.ndarray:
    """Independent parse of the MOTION rows: text after the 'Frame Time' line, float() per
    token, blank lines skipped."""
    text = path.read_text().replace("\r\n", "\n")
    after = text[text.index("Frame Time") :].split("\n", 1)[1]
    return np.array([[float(t) for t in ln.split()] for ln in after.split("\n") if ln.strip()])


@pytest.mark.real_data
@pytest.mark.parametrize(
    ("name", "joints", "channels", "frames", "frame_time", "fps", "ends", "orders"), REAL_FILES
)
def test_real_file_matches_provenance(
    real_data, name, joints, channels, frames, frame_time, fps, ends, orders
):
    path = real_data / "bvh" / name
    clip = read_bvh(path)
    skel = clip.skeleton
    assert skel.n_joints == joints
    assert skel.n_channels == channels
    assert clip.n_frames == frames
    assert clip.frame_time_s == frame_time
    assert clip.nominal_fps == fps
    assert sum(len(e) for e in skel.end_sites) == ends
    assert set(skel.rotation_orders) == orders
    assert skel.parents[0] == -1 and all(0 <= p < j for j, p in enumerate(skel.parents[1:], 1))
    # Every value equals an independent float() parse of the data rows.
    np.testing.assert_array_equal(clip.values, _data_lines(path))


@pytest.mark.real_data
def test_real_file_details(real_data):
    cmu = read_bvh(real_data / "bvh" / "01_01.bvh")
    assert {"LHipJoint", "LFingers", "RThumb"} <= set(cmu.skeleton.names)
    assert cmu.skeleton.channels[0] == (
        "Xposition", "Yposition", "Zposition", "Zrotation", "Yrotation", "Xrotation"
    )  # fmt: skip
    mixamo = read_bvh(real_data / "bvh" / "test_freebvh.bvh")
    assert mixamo.skeleton.names[0] == "mixamorig:Hips"
    assert all(n.startswith("mixamorig:") for n in mixamo.skeleton.names)
    walk = read_bvh(real_data / "bvh" / "AV_8Walk_Meredith_HVHA_Rep1.bvh")
    assert {"LeftHandThumb1", "LeftHand_End"} <= set(walk.skeleton.names)
    np.testing.assert_allclose(walk.skeleton.offsets[0], [11.2666, 35.4190, -54.3259])
    freya = read_bvh(real_data / "bvh" / "freya_edit.bvh")
    assert freya.skeleton.has_position_channels.all()


@pytest.mark.slow
@pytest.mark.real_data
@pytest.mark.parametrize("name", [r[0] for r in REAL_FILES])
def test_fast_and_strict_motion_paths_agree(real_data, name):
    data = (real_data / "bvh" / name).read_bytes()
    clip = parse_bvh(data)
    start = data.index(b"\n", data.index(b"Frame Time")) + 1
    block = data[start:]
    fast = bvh._parse_motion_fast(block, clip.skeleton.n_channels, clip.n_frames)
    strict = bvh._parse_motion_strict(block, clip.skeleton.n_channels, clip.n_frames, 1, None)
    assert fast is not None, "the real files should take the fast path"
    np.testing.assert_array_equal(fast, strict)


# --------------------------------------------------------------------------------------------
# Edge cases on small hand-written files

MIXED = """HIERARCHY
ROOT mixamorig:Hips
{
\tOFFSET 1 2 3
\tCHANNELS 6 Xposition Yposition Zposition Zrotation Xrotation Yrotation
\tJOINT Bip01.L_Thigh
\t{
\t\tOFFSET 0 -10 0
\t\tCHANNELS 3 Xrotation Yrotation Zrotation
\t\tEnd Site
\t\t{
\t\t\tOFFSET 0 -5 0
\t\t}
\t\tEnd Site
\t\t{
\t\t\tOFFSET 1 -5 0
\t\t}
\t}
\tJOINT Slider
\t{
\t\tOFFSET 0 7 0
\t\tCHANNELS 6 Xposition Yposition Zposition Yrotation Zrotation Xrotation
\t\tJOINT NoChannels
\t\t{
\t\t\tOFFSET 0 1 0
\t\t}
\t}
\tJOINT Hinge
\t{
\t\tOFFSET 2 0 0
\t\tCHANNELS 1 Zrotation
\t}
}
MOTION
Frames:2
Frame Time:0.0083
"""
ROW1 = "0.5 1. +3 10 20 30 1e1 -2.5E+1 .5 4 5 6 7 8 9 45"
ROW2 = "1 2 3 0 0 0 0 0 0 0 0 0 0 0 0 -90"


def test_edge_cases_mixed_orders_six_channel_joint_end_sites_names():
    clip = parse_bvh(MIXED + ROW1 + "\n" + ROW2 + "\n")
    skel = clip.skeleton
    assert skel.names == ("mixamorig:Hips", "Bip01.L_Thigh", "Slider", "NoChannels", "Hinge")
    assert skel.parents == (-1, 0, 0, 2, 0)
    assert skel.rotation_orders == ("ZXY", "XYZ", "YZX", "XYZ", "ZXY")
    assert [len(e) for e in skel.end_sites] == [0, 2, 0, 0, 0]
    np.testing.assert_array_equal(skel.end_sites[1], [[0, -5, 0], [1, -5, 0]])
    assert clip.frame_time_s == 0.0083
    np.testing.assert_array_equal(clip.values[0], [float(t) for t in ROW1.split()])

    euler = euler_degrees(clip)
    # Root: channels Z X Y → [z, x, y] = [10, 20, 30]; thigh X Y Z → [10, -25, 0.5].
    np.testing.assert_array_equal(euler[0, 0], [10, 20, 30])
    np.testing.assert_array_equal(euler[0, 1], [10, -25, 0.5])
    np.testing.assert_array_equal(euler[0, 2], [7, 8, 9])  # Y Z X values in channel order
    np.testing.assert_array_equal(euler[0, 3], [0, 0, 0])  # no channels: identity
    np.testing.assert_array_equal(euler[0, 4], [45, 0, 0])  # only Zrotation, order "ZXY"

    trans = local_translations(clip)
    np.testing.assert_array_equal(root_translation(clip)[0], [0.5, 1.0, 3.0])
    # The 6-channel joint's position channels REPLACE its OFFSET (0 7 0).
    np.testing.assert_array_equal(trans[0, 2], [4, 5, 6])
    np.testing.assert_array_equal(trans[0, 3], [0, 1, 0])

    # Frame 2 has no rotation except Hinge: positions follow offsets from the root at (1,2,3).
    pos = world_positions(clip)[1]
    np.testing.assert_allclose(pos[1], [1, -8, 3])
    np.testing.assert_allclose(pos[2], [1, 2, 3])  # Slider position channels are 0 0 0
    np.testing.assert_allclose(pos[3], [1, 3, 3])


def test_header_spacing_crlf_tabs_and_blank_lines():
    body = MIXED.replace("Frames:2", "Frames:\t 2").replace(
        "Frame Time:0.0083", "Frame Time:\t.0083"
    )
    body = body.replace("MOTION\n", "MOTION\n\n")
    text = (body + "  " + ROW1.replace(" ", "\t ") + "  \n\n" + ROW2 + "\n\n").replace("\n", "\r\n")
    clip = parse_bvh(text.encode())
    assert clip.frame_time_s == 0.0083
    np.testing.assert_array_equal(clip.values[0], [float(t) for t in ROW1.split()])
    np.testing.assert_array_equal(clip.values[1], [float(t) for t in ROW2.split()])


def test_channels_declared_out_of_joint_order_are_reordered():
    text = """HIERARCHY
ROOT A
{
  OFFSET 0 0 0
  JOINT B
  {
    OFFSET 0 1 0
    CHANNELS 1 Xrotation
  }
  CHANNELS 3 Xposition Yposition Zposition
}
MOTION
Frames: 1
Frame Time: 0.1
5 1 2 3
"""
    clip = parse_bvh(text)
    # File columns are B.Xrotation, A.X/Y/Zposition; our columns follow the joint order.
    np.testing.assert_array_equal(clip.values, [[1, 2, 3, 5]])
    assert clip.skeleton.channels == (("Xposition", "Yposition", "Zposition"), ("Xrotation",))


def test_zero_frames():
    clip = parse_bvh(MIXED.replace("Frames:2", "Frames: 0"))
    assert clip.values.shape == (0, 16)


# --------------------------------------------------------------------------------------------
# Malformed input: one InputError naming the file and the line


def _error(text: str) -> str:
    with pytest.raises(InputError) as info:
        parse_bvh(text, path="dance.bvh")
    message = str(info.value)
    assert message.startswith("dance.bvh: ")
    return message


GOOD = MIXED + ROW1 + "\n" + ROW2 + "\n"
N_HEADER = MIXED.count("\n")  # data rows start on line N_HEADER + 1


@pytest.mark.parametrize(
    ("text", "line", "words"),
    [
        (MIXED + ROW1 + "\n" + ROW2.replace(" 0 0 -90", " 0 -90") + "\n", N_HEADER + 2,
         "has 15 values, the hierarchy declares 16"),
        (MIXED + ROW1 + "\n", N_HEADER + 1, "file ends after 1 of 2 frames"),
        (MIXED, N_HEADER, "file ends after 0 of 2 frames"),
        (MIXED + ROW1 + "\n" + ROW2.replace("1 2 3", "1 2 0.0-7.5") + "\n", N_HEADER + 2,
         "glued"),
        (MIXED + ROW1 + "\n" + ROW2 + "\n" + ROW2 + "\n", N_HEADER + 3, "'Frames:' declares"),
        (MIXED + ROW1 + "\n" + ROW2.replace("1 2 3", "1 nan 3") + "\n", N_HEADER + 2,
         "'nan' is not a number"),
        (MIXED + ROW1 + "\n" + ROW2.replace("1 2 3", "1 1e999 3") + "\n", N_HEADER + 2,
         "not a finite number"),
        (MIXED + ROW1 + "\n" + ROW2.replace("1 2 3", "1 2,5 3") + "\n", N_HEADER + 2,
         "'2,5' is not a number"),
        (GOOD.replace("CHANNELS 3 Xrotation Yrotation Zrotation", "CHANNELS 3 Xrotation Yrotation"),
         9, "CHANNELS declares 3 channels but lists 2"),
        (GOOD.replace("CHANNELS 1 Zrotation", "CHANNELS 1 Zrotation Xrotation"), 31,
         "CHANNELS declares 1 channels but lists 2"),
        (GOOD.replace("CHANNELS 1 Zrotation", "CHANNELS 1 Wrotation"), 31, "unknown channel"),
        (GOOD.replace("OFFSET 0 -10 0", "OFFSET 0 -10-0"), 8, "glued"),
        (GOOD.replace("OFFSET 0 -10 0", "OFFSET 0 -10"), 8, "OFFSET needs 3 numbers"),
        (GOOD.replace("\t\t}\n\t}\n\tJOINT Slider", "\t\t}\n\tJOINT Slider"), 33,
         "missing '}'"),
        (GOOD.replace("Frames:2", "Frames: two"), N_HEADER - 1, "not a whole number"),
        (GOOD.replace("Frame Time:0.0083", "Frame Time: 0"), N_HEADER, "not a positive"),
        (GOOD.replace("JOINT Hinge", "JOINT Slider"), 28, "duplicate joint name"),
        (GOOD.replace("HIERARCHY", "HIERARCHIE"), 1, "expected HIERARCHY"),
        (GOOD.replace("Frame Time:", "Frame Tim:"), N_HEADER, "expected 'Frame Time: T'"),
    ],
)  # fmt: skip
def test_malformed_input_names_the_line(text, line, words):
    message = _error(text)
    assert f"line {line}:" in message, message
    assert words in message, message


def test_malformed_without_line_numbers_say_what_is_wrong():
    assert "empty file" in _error("")
    assert "MOTION" in _error(MIXED.split("MOTION")[0])
    assert "line 1:" in _error("hello world\n")


def test_missing_file_is_an_input_error(tmp_path):
    with pytest.raises(InputError, match="cannot read BVH file"):
        read_bvh(tmp_path / "absent.bvh")


# --------------------------------------------------------------------------------------------
# The fast motion path parses numbers exactly like float() and refuses what the strict path does

_number_text = st.from_regex(
    r"[+-]?([0-9]{1,7}\.?[0-9]{0,7}|\.[0-9]{1,7})([eE][+-]?[0-9]{1,2})?", fullmatch=True
)


@settings(max_examples=60, deadline=None)
@given(
    st.lists(_number_text, min_size=3, max_size=3), st.lists(_number_text, min_size=3, max_size=3)
)
def test_fast_path_equals_float(row1, row2):
    block = (" ".join(row1) + "\n" + "\t".join(row2) + "\r\n").encode()
    fast = bvh._parse_motion_fast(block, 3, 2)
    expected = np.array([[float(t) for t in row1], [float(t) for t in row2]])
    if np.isfinite(expected).all():
        assert fast is not None
        np.testing.assert_array_equal(fast, expected)
    else:
        assert fast is None


@settings(max_examples=80, deadline=None)
@given(st.text(alphabet="0123456789+-.eE", min_size=1, max_size=6))
def test_fast_path_never_accepts_what_strict_rejects(token):
    block = f"1 {token} 2\n".encode()
    fast = bvh._parse_motion_fast(block, 3, 1)
    try:
        strict = bvh._parse_motion_strict(block, 3, 1, 10, None)
    except InputError as exc:
        assert fast is None
        assert re.search(r"line 10: ", str(exc))
    else:
        assert fast is None or np.array_equal(fast, strict)
