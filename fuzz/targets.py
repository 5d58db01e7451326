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
from tests.test_faults_bvh_hypothesis import check_bvh_bytes, check_valid_doc

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
        Target("openpose", _openpose_folders(), check_openpose, "mutated OpenPose JSON folders"),
        Target("measures", _MEASURE_ARGS, check_measures, "any numbers into measure_bounds"),
        Target("split_list", st.binary(max_size=300), check_name_list, "random split files"),
    )
}

__all__ = ["TARGETS", "Hang", "Target"]
