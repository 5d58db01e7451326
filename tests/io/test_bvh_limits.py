"""BVH files of hostile size or value (issue 11, items 7 and 8): each ends in one InputError line
naming the file and the line, fast and with bounded memory, and the documented limits of
:mod:`dancedata.io.bvh_head` hold exactly at their values. Through the CLI a bad ``Frame Time``
exits 1 with one ``error:`` line, writes no version and leaves no lock or temporary folder."""

from __future__ import annotations

import os
import subprocess
import sys
import textwrap
import threading
import time
from pathlib import Path

import numpy as np
import pytest

from dancedata.errors import InputError
from dancedata.io import bvh, bvh_head
from dancedata.io.bvh import parse_bvh, read_bvh
from dancedata.store.layout import StoreLayout
from tests.helpers import REPO, run_cli

ROOT_CHANNELS = "CHANNELS 6 Xposition Yposition Zposition Zrotation Xrotation Yrotation"
JOINT_CHANNELS = "CHANNELS 3 Zrotation Xrotation Yrotation"


def rig_text(
    n_joints: int = 3,
    *,
    chain: bool = True,
    end_sites: int = 1,
    frames: int = 2,
    frame_time: str = "0.0083333",
    pad: str = "",
) -> str:
    """A BVH file: a chain (each joint the child of the previous) or a fan (every joint a child
    of the root) of ``n_joints`` joints 10 cm apart, ``end_sites`` End Sites on the last joint,
    ``frames`` rows of small angles. ``pad`` is put before the first JOINT line."""
    lines = ["HIERARCHY", "ROOT j0", "{", "OFFSET 0 0 0", ROOT_CHANNELS, pad]
    for j in range(1, n_joints):
        lines += [f"JOINT j{j}", "{", "OFFSET 0 10 0", JOINT_CHANNELS]
        if not chain:
            lines.append("}")
    lines += ["End Site", "{", "OFFSET 0 5 0", "}"] * end_sites
    lines += ["}"] * ((n_joints - 1 if chain else 0) + 1)
    n_channels = 6 + 3 * (n_joints - 1)
    lines += ["MOTION", f"Frames: {frames}", f"Frame Time: {frame_time}"]
    rng = np.random.default_rng(0)
    for _ in range(frames):
        lines.append(" ".join(f"{v:.4f}" for v in rng.uniform(-30, 30, n_channels)))
    return "\n".join(lines) + "\n"


def line_of(text: str, needle: str, nth: int = 1) -> int:
    """1-based line number of the ``nth`` occurrence of ``needle`` in ``text``."""
    at = -1
    for _ in range(nth):
        at = text.index(needle, at + 1)
    return text.count("\n", 0, at) + 1


def error_of(data: str | bytes) -> str:
    with pytest.raises(InputError) as info:
        parse_bvh(data, path="hostile.bvh")
    message = str(info.value)
    assert message.startswith("hostile.bvh: ") and "\n" not in message, message
    assert len(message) < 300, message
    return message


# --------------------------------------------------------------------------------------------
# Memory and time on files of hostile size, measured in a child process

_PEAK_SCRIPT = textwrap.dedent(
    """
    import resource, sys, time
    from dancedata.errors import InputError
    from dancedata.io.bvh import read_bvh
    start = time.perf_counter()
    try:
        clip = read_bvh(sys.argv[1])
        print("ok", clip.n_frames)
    except InputError as exc:
        print("error", exc)
    print(time.perf_counter() - start)
    # VmHWM, not ru_maxrss: ru_maxrss survives exec, so a child would report pytest's own peak
    status = open('/proc/self/status').read().split('VmHWM:')[1]
    print(int(status.split()[0]))  # KiB
    """
)


def peak_read(path: Path) -> tuple[str, float, float]:
    """read_bvh(path) in a fresh interpreter: (outcome line, seconds, peak RSS in MiB)."""
    proc = subprocess.run(
        [sys.executable, "-c", _PEAK_SCRIPT, str(path)],
        capture_output=True,
        text=True,
        timeout=120,
        cwd=REPO,
        check=True,
    )
    outcome, seconds, peak_kib = proc.stdout.strip().split("\n")
    return outcome, float(seconds), int(peak_kib) / 1024


@pytest.fixture(scope="module")
def baseline_peak_mib(tmp_path_factory) -> float:
    """Peak RSS of a child reading a small valid file: the interpreter and its imports."""
    path = tmp_path_factory.mktemp("baseline") / "small.bvh"
    path.write_text(rig_text())
    outcome, _, peak = peak_read(path)
    assert outcome == "ok 2"
    return peak


# What reading may add to the baseline for a 50 MB hostile file. Before the bounded reader the
# whole-file-on-one-line case took 1.2 GB (4.9 GB at 200 MB); now it reads 1 MiB and stops.
EXTRA_MIB = 40
HOSTILE_MB = 50


@pytest.mark.slow
def test_whole_file_on_one_line_fails_fast_with_bounded_memory(tmp_path, baseline_peak_mib):
    path = tmp_path / "one_line.bvh"
    text = rig_text(20, frames=200).replace("\n", " ")
    head, rows = text.split("Frame Time: 0.0083333 ")
    with path.open("w") as out:
        out.write(head + "Frame Time: 0.0083333 ")
        for _ in range(HOSTILE_MB * 10**6 // len(rows) + 1):
            out.write(rows)
    assert path.stat().st_size > HOSTILE_MB * 10**6
    outcome, seconds, peak = peak_read(path)
    assert outcome.startswith(f"error {path}: line 1: joint name longer than 1,000 characters")
    assert "line breaks missing?" in outcome and len(outcome) < 300
    assert seconds < 1.0
    assert peak - baseline_peak_mib < EXTRA_MIB, (peak, baseline_peak_mib)


@pytest.mark.slow
def test_frame_rows_on_one_line_fail_without_copying_the_rows(tmp_path, baseline_peak_mib):
    """The hierarchy is fine, every frame row is on one line: the reader holds the frame block
    once (50 MB) and names the line, without splitting it into millions of words."""
    path = tmp_path / "rows_one_line.bvh"
    text = rig_text(20, frames=200)
    head, rows = text.split("Frame Time: 0.0083333\n")
    rows = rows.replace("\n", " ")
    with path.open("w") as out:
        out.write(head + "Frame Time: 0.0083333\n")
        for _ in range(HOSTILE_MB * 10**6 // len(rows) + 1):
            out.write(rows)
    outcome, seconds, peak = peak_read(path)
    data_line = head.count("\n") + 2
    assert outcome.startswith(f"error {path}: line {data_line}: frame 1 has more than ")
    assert outcome.endswith("values, the hierarchy declares 63 channels")
    assert seconds < 2.0
    assert peak - baseline_peak_mib < HOSTILE_MB + EXTRA_MIB, (peak, baseline_peak_mib)


@pytest.mark.slow
def test_ten_thousand_deep_hierarchy_is_refused_with_bounded_memory(tmp_path, baseline_peak_mib):
    path = tmp_path / "deep.bvh"
    text = rig_text(10_000, frames=1)
    path.write_text(text)
    outcome, seconds, peak = peak_read(path)
    line = line_of(text, "JOINT j5000\n")  # the 5,001st joint of the chain
    assert outcome == (
        f"error {path}: line {line}: the hierarchy nests deeper than 5,000 joints "
        "(the reader's limit)"
    )
    assert seconds < 2.0
    assert peak - baseline_peak_mib < EXTRA_MIB, (peak, baseline_peak_mib)


# --------------------------------------------------------------------------------------------
# The documented limits, exactly at their values


@pytest.mark.real_data
def test_limits_are_far_above_the_real_rigs(real_data):
    """The five real files: at most 59 joints, 15 End Sites, 26-character names and chains of
    13 joints, frame times 0.008 to 0.033 s (as docs/STORE.md says); the limits are 38 to 380
    times larger."""
    joints, ends, names, depth = [], [], [], []
    for path in sorted((real_data / "bvh").glob("*.bvh")):
        clip = read_bvh(path)
        skel = clip.skeleton
        chain = [1] * skel.n_joints
        for j, p in enumerate(skel.parents[1:], start=1):
            chain[j] = chain[p] + 1
        joints.append(skel.n_joints)
        ends.append(sum(len(e) for e in skel.end_sites))
        names.append(max(map(len, skel.names)))
        depth.append(max(chain))
        low, high = bvh_head.FRAME_TIME_RANGE_S
        assert 10 * low <= clip.frame_time_s <= high / 10
    assert (max(joints), max(ends), max(names), max(depth)) == (59, 15, 26, 13)
    assert max(joints) * 100 <= bvh_head.MAX_JOINTS
    assert max(ends) * 100 <= bvh_head.MAX_END_SITES
    assert max(names) * 38 <= bvh_head.MAX_NAME_CHARS
    assert max(depth) * 380 <= bvh_head.MAX_DEPTH


@pytest.mark.slow
def test_depth_limit_is_exact():
    assert parse_bvh(rig_text(bvh_head.MAX_DEPTH, frames=1)).skeleton.n_joints == 5_000
    text = rig_text(bvh_head.MAX_DEPTH + 1)
    message = error_of(text)
    assert f"line {line_of(text, 'JOINT j5000')}: the hierarchy nests deeper than 5,000" in message


@pytest.mark.slow
def test_joint_limit_is_exact():
    clip = parse_bvh(rig_text(bvh_head.MAX_JOINTS, chain=False, frames=1))
    assert clip.skeleton.n_joints == 10_000 and set(clip.skeleton.parents[1:]) == {0}
    text = rig_text(bvh_head.MAX_JOINTS + 1, chain=False, frames=1)
    assert f"line {line_of(text, 'JOINT j10000')}: more than 10,000 joints" in error_of(text)


def test_end_site_limit_is_exact():
    clip = parse_bvh(rig_text(2, end_sites=bvh_head.MAX_END_SITES))
    assert len(clip.skeleton.end_sites[1]) == 10_000
    text = rig_text(2, end_sites=bvh_head.MAX_END_SITES + 1)
    line = line_of(text, "End Site", 10_001)
    assert f"line {line}: more than 10,000 End Sites" in error_of(text)


@pytest.mark.parametrize(
    ("old", "new", "words"),
    [
        ("ROOT j0", "ROOT " + "n" * 1001, "joint name longer than 1,000 characters"),
        ("ROOT j0", "ROOT " + "a " * 600, "joint name longer than 1,000 characters"),
        ("OFFSET 0 10 0", "OFFSET 0 10 " + "1" * 5000, "a word of more than 4,096 bytes"),
        ("Frames: 2", "Frames: " + "9" * 5000, "expected 'Frames: N', found a line of more than"),
        ("Frames: 2", "Frames: " + "9" * 4000, "frame count '9999"),
        ("Frames: 2", "Frames: " + "9" * 19, "is not plausible (more than 18 digits)"),
        ("Frame Time: 0.0083333", "Frame Time: " + "1" * 5000, "found a line of more than"),
        (JOINT_CHANNELS, "CHANNELS 7 Zrotation", "a joint has at most 6"),
        (JOINT_CHANNELS, "CHANNELS " + "9" * 4000, "a joint has at most 6"),
        (JOINT_CHANNELS, JOINT_CHANNELS + " Xposition" * 400, "but lists more than"),
    ],
)
def test_long_words_lines_and_counts_give_one_short_line(old, new, words):
    message = error_of(rig_text().replace(old, new, 1))
    assert words in message, message


def _with_first_value(text: str, value: str) -> str:
    """``text`` with the first value of its last frame row replaced by ``value``."""
    head, last = text.rstrip("\n").rsplit("\n", 1)
    return head + "\n" + " ".join([value, *last.split()[1:]]) + "\n"


def test_long_values_are_numbers_on_both_paths_and_bad_ones_fail_fast():
    """A 300-digit value is a number for the fast and the strict path alike; a million digits
    ending in 'x' is refused in well under a second (the number pattern used to backtrack:
    5 s for 10,000 digits, quadratic) with a short message."""
    text = _with_first_value(rig_text(), "5" * 300)
    clip = parse_bvh(text)
    assert clip.values[-1, 0] == float("5" * 300)
    block = text.split("Frame Time: 0.0083333\n")[1].encode()
    strict = bvh._parse_motion_strict(block, clip.skeleton.n_channels, 2, 1, None)
    np.testing.assert_array_equal(strict, clip.values)
    bad = _with_first_value(rig_text(), "1" * 10**6 + "x")
    start = time.perf_counter()
    message = error_of(bad)
    assert time.perf_counter() - start < 1.0
    assert f"line {bad.count(chr(10))}: '1111" in message and "is not a number" in message
    start = time.perf_counter()
    message = error_of(rig_text().replace("OFFSET 0 10 0", "OFFSET 0 10 " + "1" * 4000 + "x"))
    assert time.perf_counter() - start < 1.0 and "OFFSET: '1111" in message


@pytest.mark.slow
def test_head_past_64_mib_is_refused(tmp_path):
    path = tmp_path / "padded.bvh"
    with path.open("w") as out:
        out.write("HIERARCHY\nROOT j0\n{\n")
        out.write((" " * 1023 + "\n") * (bvh_head.MAX_HEADER_BYTES // 1024 + 1))
        out.write("OFFSET 0 0 0\n}\nMOTION\n")
    with pytest.raises(InputError, match=r"line \d+: no frame data within the first 64 MiB"):
        read_bvh(path)


@pytest.mark.slow
@pytest.mark.parametrize("pad_mib", [0.99, 1.0, 1.01, 3.99, 4.0, 17.3])
def test_reading_in_growing_prefixes_equals_parsing_the_whole_file(tmp_path, pad_mib):
    """A head longer than the first read (1 MiB), with words and the MOTION line at or across
    the read boundaries, is read exactly as parse_bvh reads the bytes."""
    pad_bytes = int(pad_mib * 2**20)
    text = rig_text(4, pad="\n" * (pad_bytes // 2) + " " * (pad_bytes - pad_bytes // 2))
    path = tmp_path / "padded.bvh"
    path.write_bytes(text.encode())
    clip, reference = read_bvh(path), parse_bvh(path.read_bytes())
    assert clip.skeleton.same_hierarchy(reference.skeleton)
    np.testing.assert_array_equal(clip.values, reference.values)
    assert clip.skeleton.names == ("j0", "j1", "j2", "j3")
    # The same file with a bad row: the line number counts the padding lines.
    bad = text.rstrip("\n").rsplit("\n", 1)[0] + "\n1 2 x\n"
    path.write_bytes(bad.encode())
    with pytest.raises(InputError, match=rf"line {bad.count(chr(10))}: 'x' is not a number"):
        read_bvh(path)


def test_boundary_cases_of_the_first_read(tmp_path):
    """The MOTION line and a joint name straddling offset 1 MiB."""
    for name_at in range(2**20 - 12, 2**20 + 4, 3):
        head = "HIERARCHY\nROOT j0\n{\nOFFSET 0 0 0\n" + ROOT_CHANNELS + "\n"
        pad = " " * (name_at - len(head) - len("JOINT "))
        text = head + pad + "JOINT joint_name_here\n{\nOFFSET 0 1 0\n}\n}\nMOTION\nFrames: 1\n"
        text += "Frame Time: 0.01\n1 2 3 4 5 6\n"
        path = tmp_path / "boundary.bvh"
        path.write_text(text)
        assert read_bvh(path).skeleton.names == ("j0", "joint_name_here")
    for motion_at in range(2**20 - 8, 2**20 + 2):
        head = rig_text(2, frames=1).split("MOTION")[0]
        text = head[:-1] + " " * (motion_at - len(head)) + "\nMOTION\nFrames: 0\nFrame Time: 1\n"
        path.write_text(text)
        assert read_bvh(path).n_frames == 0


def test_classic_mac_line_endings_through_read_bvh(tmp_path):
    text = rig_text(3)
    path = tmp_path / "mac.bvh"
    path.write_bytes(text.replace("\n", "\r").encode())
    np.testing.assert_array_equal(read_bvh(path).values, parse_bvh(text).values)
    # CR-only for the first 2 MiB, LF later: not a Mac file, read_bvh agrees with parse_bvh.
    mixed = rig_text(3, pad="\r" * 2**21).replace("\n", "\r", 8).encode()
    path.write_bytes(mixed)
    with pytest.raises(InputError) as from_file:
        read_bvh(path)
    with pytest.raises(InputError) as from_bytes:
        parse_bvh(mixed, path=path)
    assert str(from_file.value) == str(from_bytes.value)
    assert "line 1: joint name" in str(from_file.value)


def test_read_bvh_from_a_pipe(tmp_path):
    """A FIFO cannot seek: the head is read in prefixes, then the whole stream parsed."""
    fifo = tmp_path / "pipe.bvh"
    os.mkfifo(fifo)
    text = rig_text(4, pad=" " * 3 * 2**20)
    writer = threading.Thread(target=fifo.write_text, args=(text,))
    writer.start()
    clip = read_bvh(fifo)
    writer.join()
    np.testing.assert_array_equal(clip.values, parse_bvh(text).values)


# --------------------------------------------------------------------------------------------
# Frame Time: accepted range 1e-4 s to 10 s (10,000 to 0.1 frames per second)


@pytest.mark.parametrize(
    "frame_time", ["5e-324", "1e-300", "1e-5", "0.0000999", "10.0001", "1e300"]
)
def test_frame_time_outside_the_range_is_refused(frame_time):
    message = error_of(rig_text(frame_time=frame_time))
    line = line_of(rig_text(), "Frame Time")
    assert message == (
        f"hostile.bvh: line {line}: Frame Time {frame_time} s is outside the accepted 0.0001 to "
        "10 s (10,000 to 0.1 frames per second)"
    )


@pytest.mark.parametrize("frame_time", ["0", "-0.01", "inf", "nan", "-inf", "1e999", "x"])
def test_frame_time_not_positive_or_not_finite_is_refused(frame_time):
    message = error_of(rig_text(frame_time=frame_time))
    assert f"Frame Time {frame_time!r} is not a positive number" in message


@pytest.mark.parametrize("frame_time", ["0.0001", "1e-4", "10", "10.0", "1", ".0083333"])
def test_frame_time_at_the_bounds_is_accepted(frame_time):
    clip = parse_bvh(rig_text(frame_time=frame_time))
    assert clip.frame_time_s == float(frame_time)
    assert 0.1 <= clip.nominal_fps <= 10_000


# --------------------------------------------------------------------------------------------
# Through the CLI: one line, exit 1, nothing written, the lock released


def _store_is_clean(store: Path) -> None:
    layout = StoreLayout(store)
    assert layout.committed_versions() == []
    assert layout.temp_dirs() == []
    assert not (store / ".lock").exists()


@pytest.mark.slow
@pytest.mark.parametrize("frame_time", ["5e-324", "1e-300"])
def test_cli_ingest_refuses_a_bad_frame_time_in_one_line(tmp_path, frame_time):
    path = tmp_path / "tiny_time.bvh"
    path.write_text(text := rig_text(frame_time=frame_time))
    store = tmp_path / "store"
    start = time.perf_counter()
    proc = run_cli("ingest", "bvh", str(path), "--store", str(store), check=False)
    assert proc.returncode == 1, proc.stderr
    errors = [line for line in proc.stderr.splitlines() if "error" in line.lower()]
    assert len(errors) == 1 and "Traceback" not in proc.stderr, proc.stderr
    assert errors[0].endswith(
        f"error: {path}: line {line_of(text, 'Frame Time')}: Frame Time {frame_time} s is "
        "outside the accepted 0.0001 to 10 s (10,000 to 0.1 frames per second)"
    ), errors[0]
    assert time.perf_counter() - start < 60
    _store_is_clean(store)
    # The lock is free: a good file goes in at once.
    good = tmp_path / "good.bvh"
    good.write_text(rig_text())
    run_cli("ingest", "bvh", str(good), "--store", str(store), "--no-size-check")
    assert len(StoreLayout(store).committed_versions()) == 1


@pytest.mark.slow
def test_cli_skips_a_bad_frame_time_and_records_why(tmp_path):
    bad, good = tmp_path / "bad.bvh", tmp_path / "good.bvh"
    bad.write_text(rig_text(frame_time="5e-324"))
    good.write_text(rig_text())
    store = tmp_path / "store"
    run_cli(
        "ingest", "bvh", str(bad), str(good), "--store", str(store), "--no-size-check",
        "--on-error", "skip",
    )  # fmt: skip
    layout = StoreLayout(store)
    (version,) = layout.committed_versions()
    skipped = layout.read_manifest(version)["skipped"]
    assert len(skipped) == 1 and skipped[0]["path"].endswith("bad.bvh")
    assert "Frame Time 5e-324 s is outside the accepted" in skipped[0]["error"]


@pytest.mark.parametrize("fps", [1e300, 1e-300, 20_000.0, 0.05, 0.0, -30.0, float("nan")])
def test_resampling_target_outside_the_accepted_rates_is_refused(fps):
    """``--fps`` takes the same range as Frame Time: 0.1 to 10,000 frames per second (1e300
    crashed the resampler with a ValueError, 1e-300 was stored as such)."""
    from dancedata.ingest.bvh import BvhIngestOptions

    with pytest.raises(InputError, match=r"--fps must lie in 0.1 to 10,000 frames per second"):
        BvhIngestOptions(fps=fps).check()
    BvhIngestOptions(fps=bvh_head.FPS_RANGE[1]).check()
    BvhIngestOptions(fps=bvh_head.FPS_RANGE[0]).check()
