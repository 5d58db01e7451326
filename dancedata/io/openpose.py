"""Read a folder of OpenPose per-frame ``*_keypoints.json`` files into ragged arrays.

OpenPose writes one JSON file per video frame, named ``<stem>_<frame:012d>_keypoints.json``, each
holding ``{"version": 1.3, "people": [{"person_id": [-1], "pose_keypoints_2d": [x, y, c, ...]}]}``.
Coordinates are pixels in the source video (origin top-left, y down); ``c`` is the detector's
confidence in [0, 1], and an undetected joint is written as ``0, 0, 0``.

The frame index is the trailing number of the file name, taken as the index of the *video* frame
(OpenPose numbers from 0). Gaps in the numbering are frames with no file: they are kept as missing
frames (``present[f] == False``), never closed up, so pose frame ``f`` stays at time ``f / fps``.

People are ragged (0..n per frame), so they are returned concatenated, with an offsets index:
the people of frame ``f`` are rows ``frame_offsets[f]:frame_offsets[f + 1]`` of ``keypoints``.
This is the layout a Zarr v3 store can hold without ragged arrays.

The body model is detected from the keypoint count: 25 joints = BODY_25, 18 = COCO (OpenPose's
18-joint COCO model with a synthetic neck), by majority over the files, so a stray file with another
count is the one reported as wrong. Raw values are kept as written (zeros for undetected
joints); turning them into NaN + mask is the tracker's job (:mod:`dancedata.compute.pose_tracking`).
"""

from __future__ import annotations

import json
import math
import re
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from dancedata.errors import InputError
from dancedata.io.frame_limits import check_frame_span

_FILE_RE = re.compile(r"^(?P<prefix>.*?)_?(?P<index>\d+)_keypoints\.json$")


@dataclass(frozen=True)
class Skeleton:
    """A 2-d keypoint layout: joint names and a parent per joint (-1 for the root).

    ``parents`` form a tree used for drawing bones and for forward-kinematics-free checks
    (bone lengths); it is not the detector's PAF pair list.
    """

    name: str
    joints: tuple[str, ...]
    parents: tuple[int, ...]

    @property
    def n_joints(self) -> int:
        return len(self.joints)

    def bones(self) -> list[tuple[int, int]]:
        """(parent, child) index pairs, one per non-root joint."""
        return [(p, c) for c, p in enumerate(self.parents) if p >= 0]

    def to_dict(self) -> dict:
        """The ``skeleton`` attribute of the contract: ``name``, ``joints``, ``parents``."""
        return {"name": self.name, "joints": list(self.joints), "parents": list(self.parents)}


# OpenPose BODY_25 (output order of poseParameters.cpp), rooted at MidHip.
BODY_25 = Skeleton(
    name="openpose_body25",
    joints=(
        "Nose",
        "Neck",
        "RShoulder",
        "RElbow",
        "RWrist",
        "LShoulder",
        "LElbow",
        "LWrist",
        "MidHip",
        "RHip",
        "RKnee",
        "RAnkle",
        "LHip",
        "LKnee",
        "LAnkle",
        "REye",
        "LEye",
        "REar",
        "LEar",
        "LBigToe",
        "LSmallToe",
        "LHeel",
        "RBigToe",
        "RSmallToe",
        "RHeel",
    ),
    parents=(1, 8, 1, 2, 3, 1, 5, 6, -1, 8, 9, 10, 8, 12, 13, 0, 0, 15, 16, 14, 19, 14, 11, 22, 11),
)

# OpenPose COCO-18 (COCO-17 plus a Neck at index 1), rooted at Neck.
COCO_18 = Skeleton(
    name="openpose_coco18",
    joints=(
        "Nose",
        "Neck",
        "RShoulder",
        "RElbow",
        "RWrist",
        "LShoulder",
        "LElbow",
        "LWrist",
        "RHip",
        "RKnee",
        "RAnkle",
        "LHip",
        "LKnee",
        "LAnkle",
        "REye",
        "LEye",
        "REar",
        "LEar",
    ),
    parents=(1, -1, 1, 2, 3, 1, 5, 6, 1, 8, 9, 1, 11, 12, 0, 0, 14, 15),
)

SKELETONS_BY_COUNT: dict[int, Skeleton] = {25: BODY_25, 18: COCO_18}
SKELETONS_BY_NAME: dict[str, Skeleton] = {"BODY_25": BODY_25, "COCO": COCO_18, "COCO_18": COCO_18}


@dataclass(frozen=True)
class OpenPoseFrames:
    """All people of all frames of one OpenPose output folder.

    Attributes:
        folder: the folder read.
        skeleton: BODY_25 or COCO-18.
        version: the ``version`` field of the first file (None when absent).
        keypoints: (P, J, 3) float32, all people of all frames concatenated: x, y in pixels,
            confidence in [0, 1]; undetected joints as OpenPose wrote them (0, 0, 0).
        person_ids: (P,) int64, OpenPose ``person_id`` (-1 when OpenPose did not track).
        frame_offsets: (F + 1,) int64; people of frame f are rows ``frame_offsets[f]:[f + 1]``.
        present: (F,) bool, True where a JSON file exists for the frame (a file with an empty
            ``people`` list is present with zero people).
        files: (F,) the file name of each frame, "" for missing frames.
    """

    folder: Path
    skeleton: Skeleton
    version: str | None
    keypoints: np.ndarray
    person_ids: np.ndarray
    frame_offsets: np.ndarray
    present: np.ndarray
    files: tuple[str, ...]

    @property
    def n_frames(self) -> int:
        """Frames from 0 to the highest numbered file, missing ones included."""
        return int(self.present.shape[0])

    @property
    def n_people(self) -> np.ndarray:
        """(F,) int64 number of people in each frame."""
        return np.diff(self.frame_offsets)

    def frame_of_row(self) -> np.ndarray:
        """(P,) int64 frame index of each row of ``keypoints``."""
        return np.repeat(np.arange(self.n_frames, dtype=np.int64), self.n_people)

    def people(self, frame: int) -> tuple[np.ndarray, np.ndarray]:
        """(n, J, 3) keypoints and (n,) person ids of one frame."""
        lo, hi = int(self.frame_offsets[frame]), int(self.frame_offsets[frame + 1])
        return self.keypoints[lo:hi], self.person_ids[lo:hi]


def keypoint_file_prefix(name: str) -> str | None:
    """The part of an OpenPose file name before its frame number (``"video"`` for
    ``video_000000000012_keypoints.json``), or None for other names."""
    if not name.endswith("_keypoints.json"):
        return None
    match = _FILE_RE.match(name)
    return None if match is None else match.group("prefix")


def list_keypoint_files(folder: str | Path, prefix: str | None = None) -> dict[int, Path]:
    """Map frame index → file for every ``*_keypoints.json`` in ``folder`` (not recursive).

    ``prefix`` keeps only files whose name before the frame number equals it (for folders
    holding several videos' output; ``prefix="video"`` keeps ``video_000000000012_keypoints.json``).
    Two files with the same frame index is an error: the folder mixes videos.
    """
    root = Path(folder)
    if not root.is_dir():
        raise InputError("not a folder of OpenPose JSON files", root)
    found: dict[int, Path] = {}
    for path in root.iterdir():
        if not path.name.endswith("_keypoints.json") or not path.is_file():
            continue
        match = _FILE_RE.match(path.name)
        if match is None:
            raise InputError("no frame number before '_keypoints.json' in the file name", path)
        if prefix is not None and match.group("prefix") != prefix:
            continue
        digits = match.group("index")
        if len(digits) > 15:  # OpenPose writes 12 digits; int() of thousands of digits is slow
            raise InputError(f"frame number of {len(digits)} digits in the file name", path)
        index = int(digits)
        if index in found:
            raise InputError(
                f"frame {index} also comes from {found[index].name}: the folder mixes the output "
                "of several videos; pass a prefix to choose one",
                path,
            )
        found[index] = path
    if not found:
        what = f"with prefix {prefix!r} " if prefix is not None else ""
        raise InputError(f"no *_keypoints.json files {what}in the folder", root)
    largest = max(found)
    check_frame_span(largest, len(found), found[largest], "files")
    return dict(sorted(found.items()))


def _person_id(person: dict, path: Path) -> int:
    raw = person.get("person_id", -1)
    if isinstance(raw, list):  # OpenPose >= 1.3 writes [id]
        raw = raw[0] if raw else -1
    if isinstance(raw, bool) or not isinstance(raw, int | float) or not math.isfinite(raw):
        raise InputError(f"person_id {raw!r} is not an integer", path)
    return int(raw)


def _pose_values(person: dict, path: Path, k: int) -> list:
    for key in ("pose_keypoints_2d", "pose_keypoints"):  # the second is OpenPose < 1.2
        if key in person:
            values = person[key]
            break
    else:
        raise InputError(f"person {k} has no 'pose_keypoints_2d'", path)
    if not isinstance(values, list):
        raise InputError(f"person {k}: 'pose_keypoints_2d' is not a list", path)
    return values


MAX_JSON_BYTES = 16 << 20  # one frame: 25 body + 70 face + 42 hand points for ~100 people is 1 MB
MAX_INT_DIGITS = 20  # an integer in a keypoints file is a person id or a 0/1 coordinate
# values of one frame, counted from commas and opening brackets before parsing: ~100 people of
# 137 points (411 numbers each) are ~41,000; a parsed value costs 50-100 bytes whatever its text,
# so 16 MiB of "[]," (5.6 million lists) took 535 MB
MAX_JSON_VALUES = 1_000_000


def _bounded_int(text: str) -> int:
    """JSON integers of at most :data:`MAX_INT_DIGITS` digits (a 5,000-digit number would
    otherwise cost seconds or raise deep inside ``json``)."""
    if len(text) > MAX_INT_DIGITS:
        raise ValueError(f"an integer of {len(text)} digits")
    return int(text)


def _bounded_float(text: str) -> float:
    """JSON numbers with a fraction or exponent, at most 40 characters long."""
    if len(text) > 40:
        raise ValueError(f"a number of {len(text)} characters")
    return float(text)


def parse_keypoints_json(data: bytes, path: Path) -> tuple[str | None, list[int], list[list]]:
    """Parse one file's bytes → (version, person ids, flat keypoint lists); errors name ``path``."""
    try:
        text = data.decode("utf-8-sig")
    except UnicodeDecodeError as exc:
        raise InputError(f"not UTF-8 text (byte {exc.start})", path) from None
    if len(data) > MAX_JSON_BYTES:
        raise InputError(f"{len(data)} bytes: more than {MAX_JSON_BYTES} for one frame", path)
    values = data.count(b",") + data.count(b"[") + data.count(b"{")
    if values > MAX_JSON_VALUES:
        raise InputError(
            f"up to {values:,} JSON values: more than {MAX_JSON_VALUES:,} for one frame", path
        )
    try:
        doc = json.loads(text, parse_int=_bounded_int, parse_float=_bounded_float)
    except json.JSONDecodeError as exc:
        hint = " (file truncated?)" if exc.pos >= len(text.rstrip()) - 1 else ""
        raise InputError(
            f"not valid JSON{hint}: {exc.msg} at line {exc.lineno} column {exc.colno}", path
        ) from None
    except RecursionError:
        raise InputError("JSON nested too deeply (not an OpenPose keypoints file)", path) from None
    except ValueError as exc:  # _bounded_int
        raise InputError(f"not an OpenPose keypoints file: {exc}", path) from None
    if not isinstance(doc, dict):
        raise InputError("top level is not a JSON object", path)
    if "people" not in doc:
        raise InputError("no 'people' list (not an OpenPose keypoints file?)", path)
    people = doc["people"]
    if not isinstance(people, list):
        raise InputError("'people' is not a list", path)
    version = doc.get("version")
    ids: list[int] = []
    flats: list[list] = []
    for k, person in enumerate(people):
        if not isinstance(person, dict):
            raise InputError(f"person {k} is not a JSON object", path)
        ids.append(_person_id(person, path))
        flats.append(_pose_values(person, path, k))
    return (None if version is None else str(version)), ids, flats


def _to_joints(flat: list, n_joints: int, path: Path, k: int) -> np.ndarray:
    if len(flat) != 3 * n_joints:
        raise InputError(
            f"person {k} has {len(flat)} pose values, expected {3 * n_joints} "
            f"({n_joints} joints × x, y, c)",
            path,
        )
    try:
        arr = np.asarray(flat, dtype=np.float64)
    except (TypeError, ValueError):
        raise InputError(f"person {k}: pose values are not all numbers", path) from None
    if arr.ndim != 1:
        raise InputError(f"person {k}: pose values are not a flat list of numbers", path)
    return arr.reshape(n_joints, 3)


def _detect_skeleton(flat: list, path: Path) -> Skeleton:
    if len(flat) % 3 == 0 and len(flat) // 3 in SKELETONS_BY_COUNT:
        return SKELETONS_BY_COUNT[len(flat) // 3]
    raise InputError(
        f"{len(flat)} pose values: expected 75 (BODY_25, 25 joints) or 54 (COCO, 18 joints)", path
    )


def _majority_skeleton(parsed: dict[int, tuple[Path, list[list]]]) -> Skeleton | None:
    """The body model most files use (by their first person's value count); ties go to the
    earliest file. None when no file has a person with a BODY_25 or COCO value count."""
    votes: dict[int, int] = {}
    first_seen: dict[int, int] = {}
    for index, (_, flats) in parsed.items():
        if not flats or not isinstance(flats[0], list):
            continue
        n = len(flats[0])
        if n % 3 or n // 3 not in SKELETONS_BY_COUNT:
            continue
        votes[n // 3] = votes.get(n // 3, 0) + 1
        first_seen.setdefault(n // 3, index)
    if not votes:
        return None
    best = max(votes, key=lambda k: (votes[k], -first_seen[k]))
    return SKELETONS_BY_COUNT[best]


BadFileHandler = Callable[[Path, str], None]


def read_openpose_folder(
    folder: str | Path,
    prefix: str | None = None,
    model: str | None = None,
    on_bad_file: BadFileHandler | None = None,
) -> OpenPoseFrames:
    """Read every ``*_keypoints.json`` of ``folder`` (see the module docstring for the layout).

    Args:
        folder: OpenPose ``--write_json`` output folder.
        prefix: keep only files whose name before the frame number equals this.
        model: "BODY_25" or "COCO" to require a body model; default: the model most files use,
            told from the keypoint count of each file's first person (ties: the earliest file).
        on_bad_file: called with (file, problem) for each unreadable or malformed file, which
            then counts as a missing frame (``present`` False); default: raise instead.

    Raises:
        InputError: naming the file, for a missing folder, no files, a non-UTF-8 or truncated or
            otherwise invalid JSON file, a missing ``people`` list, or a keypoint count that is not
            BODY_25/COCO or differs from the model (unless ``on_bad_file`` takes file errors).
    """
    root = Path(folder)
    files = list_keypoint_files(root, prefix)
    skeleton: Skeleton | None = None
    if model is not None:
        if model.upper() not in SKELETONS_BY_NAME:
            raise InputError(f"unknown OpenPose model {model!r}; use BODY_25 or COCO", root)
        skeleton = SKELETONS_BY_NAME[model.upper()]

    def bad(exc: InputError) -> None:
        if on_bad_file is None:
            raise exc
        on_bad_file(Path(exc.path) if exc.path else root, exc.problem)

    parsed: dict[int, tuple[Path, list[list]]] = {}
    ids_by_frame: dict[int, list[int]] = {}
    version: str | None = None
    first = True
    for index, path in files.items():
        try:
            try:
                data = path.read_bytes()
            except OSError as exc:
                raise InputError(f"cannot read: {exc.strerror}", path) from None
            file_version, ids, flats = parse_keypoints_json(data, path)
        except InputError as exc:
            bad(exc)
            continue
        if first:
            version, first = file_version, False
        parsed[index] = (path, flats)
        ids_by_frame[index] = ids
    if skeleton is None:
        skeleton = _majority_skeleton(parsed)
    if skeleton is None:
        for path, flats in parsed.values():  # only unknown counts, or nobody at all
            if flats:
                _detect_skeleton(flats[0], path)  # raises, naming the first such file
        raise InputError(
            "no person in any frame, so the body model cannot be told; pass model='BODY_25' or "
            "'COCO'",
            root,
        )

    n_frames = max(files) + 1
    present = np.zeros(n_frames, dtype=bool)
    counts = np.zeros(n_frames, dtype=np.int64)
    names = [""] * n_frames
    rows: list[np.ndarray] = []
    ids_all: list[int] = []
    for index, (path, flats) in parsed.items():
        try:
            joints = [_to_joints(flat, skeleton.n_joints, path, k) for k, flat in enumerate(flats)]
        except InputError as exc:
            bad(exc)
            continue
        rows.extend(joints)
        ids_all.extend(ids_by_frame[index])
        present[index] = True
        counts[index] = len(flats)
        names[index] = path.name
    keypoints = (
        np.stack(rows).astype(np.float32)
        if rows
        else np.zeros((0, skeleton.n_joints, 3), np.float32)
    )
    offsets = np.zeros(n_frames + 1, dtype=np.int64)
    np.cumsum(counts, out=offsets[1:])
    return OpenPoseFrames(
        folder=root,
        skeleton=skeleton,
        version=version,
        keypoints=keypoints,
        person_ids=np.asarray(ids_all, dtype=np.int64),
        frame_offsets=offsets,
        present=present,
        files=tuple(names),
    )
