"""OpenPose JSON folder reader: real raga examples, numbering, body models, malformed files."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from dancedata.errors import InputError
from dancedata.io.openpose import BODY_25, COCO_18, keypoint_file_prefix, read_openpose_folder

RAGA = Path("openpose")


def _write(
    folder: Path,
    index: int,
    people: list,
    prefix: str = "video",
    width: int = 12,
    version: float = 1.3,
) -> Path:
    folder.mkdir(parents=True, exist_ok=True)
    path = folder / f"{prefix}_{index:0{width}d}_keypoints.json"
    path.write_text(json.dumps({"version": version, "people": people}))
    return path


def _person(n_joints: int, seed: int, person_id=None) -> dict:
    values = np.random.default_rng(seed).uniform(0, 500, (n_joints, 3))
    values[:, 2] = np.round(values[:, 2] / 500, 3)
    out = {"pose_keypoints_2d": values.ravel().round(3).tolist()}
    if person_id is not None:
        out["person_id"] = person_id
    return out


# ----------------------------------------------------------------------------- real data


@pytest.mark.real_data
def test_raga_1person_body25_matches_the_raw_json(real_data: Path) -> None:
    folder = real_data / RAGA / "raga_example_1person" / "output_json"
    frames = read_openpose_folder(folder)
    assert frames.skeleton is BODY_25
    assert frames.n_frames == 125 and frames.present.all()
    assert frames.version == "1.3"
    assert (frames.n_people == 1).all()
    assert (frames.person_ids == -1).all()
    # Independent reading of one file with the json module.
    raw = json.loads((folder / "video_000000000012_keypoints.json").read_text())
    expected = np.asarray(raw["people"][0]["pose_keypoints_2d"], np.float32).reshape(25, 3)
    got, ids = frames.people(12)
    np.testing.assert_array_equal(got[0], expected)
    assert frames.files[12] == "video_000000000012_keypoints.json"


@pytest.mark.real_data
def test_raga_3people_has_three_people_in_every_frame(real_data: Path) -> None:
    frames = read_openpose_folder(real_data / RAGA / "raga_example_3people" / "output_json")
    assert frames.n_frames == 125
    assert (frames.n_people == 3).all()
    assert frames.keypoints.shape == (375, 25, 3)
    np.testing.assert_array_equal(frames.frame_of_row(), np.repeat(np.arange(125), 3))


# ----------------------------------------------------------------------------- numbering


def test_frames_sorted_numerically_and_gaps_kept_missing(tmp_path: Path) -> None:
    # Unpadded numbers: lexical order would put 10 before 2.
    for index in (0, 1, 2, 10):
        _write(tmp_path, index, [_person(25, index)], width=1)
    frames = read_openpose_folder(tmp_path)
    assert frames.n_frames == 11
    np.testing.assert_array_equal(np.flatnonzero(frames.present), [0, 1, 2, 10])
    np.testing.assert_array_equal(frames.n_people, [1, 1, 1] + [0] * 7 + [1])
    expected = np.asarray(_person(25, 10)["pose_keypoints_2d"], np.float32).reshape(25, 3)
    np.testing.assert_array_equal(frames.people(10)[0][0], expected)
    assert frames.files[5] == ""


def test_empty_people_list_is_a_present_frame_with_nobody(tmp_path: Path) -> None:
    _write(tmp_path, 0, [_person(25, 0)])
    _write(tmp_path, 1, [])
    frames = read_openpose_folder(tmp_path)
    assert frames.present.tolist() == [True, True]
    assert frames.n_people.tolist() == [1, 0]


def test_person_id_forms(tmp_path: Path) -> None:
    _write(tmp_path, 0, [_person(25, 0, [4]), _person(25, 1, 7), _person(25, 2)])
    frames = read_openpose_folder(tmp_path)
    assert frames.person_ids.tolist() == [4, 7, -1]


def test_prefix_separates_two_videos_in_one_folder(tmp_path: Path) -> None:
    _write(tmp_path, 0, [_person(25, 0)], prefix="a")
    _write(tmp_path, 0, [_person(25, 1)], prefix="b")
    _write(tmp_path, 1, [_person(25, 2)], prefix="b")
    with pytest.raises(InputError, match="mixes the output of several videos"):
        read_openpose_folder(tmp_path)
    assert read_openpose_folder(tmp_path, prefix="b").n_frames == 2
    assert read_openpose_folder(tmp_path, prefix="a").n_frames == 1


# ----------------------------------------------------------------------------- body models


def test_coco18_detected_from_keypoint_count(tmp_path: Path) -> None:
    _write(tmp_path, 0, [_person(18, 0)])
    frames = read_openpose_folder(tmp_path)
    assert frames.skeleton is COCO_18
    assert frames.keypoints.shape == (1, 18, 3)


@pytest.mark.parametrize("skeleton", [BODY_25, COCO_18])
def test_skeleton_parents_form_one_tree(skeleton) -> None:
    parents = skeleton.parents
    assert len(parents) == len(skeleton.joints) == len(set(skeleton.joints))
    assert parents.count(-1) == 1
    for joint in range(len(parents)):  # every joint reaches the root without a cycle
        seen, j = set(), joint
        while parents[j] != -1:
            assert j not in seen
            seen.add(j)
            j = parents[j]
    assert len(skeleton.bones()) == len(parents) - 1


def test_skeleton_joint_order_is_openposes() -> None:
    # Indices from the OpenPose output-format documentation.
    assert (BODY_25.joints[0], BODY_25.joints[1], BODY_25.joints[8]) == ("Nose", "Neck", "MidHip")
    assert (BODY_25.joints[19], BODY_25.joints[24]) == ("LBigToe", "RHeel")
    assert (COCO_18.joints[8], COCO_18.joints[11], COCO_18.joints[17]) == ("RHip", "LHip", "LEar")
    # Bones join anatomical neighbours, e.g. RWrist's parent is RElbow.
    assert BODY_25.joints[BODY_25.parents[BODY_25.joints.index("RWrist")]] == "RElbow"
    assert COCO_18.joints[COCO_18.parents[COCO_18.joints.index("LAnkle")]] == "LKnee"


def test_no_people_anywhere_needs_a_model(tmp_path: Path) -> None:
    _write(tmp_path, 0, [])
    with pytest.raises(InputError, match="body model cannot be told"):
        read_openpose_folder(tmp_path)
    frames = read_openpose_folder(tmp_path, model="COCO")
    assert frames.keypoints.shape == (0, 18, 3)


def test_forced_model_rejects_other_counts(tmp_path: Path) -> None:
    bad = _write(tmp_path, 0, [_person(25, 0)])
    with pytest.raises(InputError, match="expected 54") as info:
        read_openpose_folder(tmp_path, model="COCO")
    assert str(bad) in str(info.value)


# ----------------------------------------------------------------------------- malformed


def _valid_doc() -> dict:
    return {"version": 1.3, "people": [_person(25, 0)]}


MALFORMED = {
    "missing_people": (json.dumps({"version": 1.3}).encode(), "no 'people' list"),
    "people_not_list": (json.dumps({"people": {}}).encode(), "'people' is not a list"),
    "wrong_count": (
        json.dumps({"people": [{"pose_keypoints_2d": [1.0] * 74}]}).encode(),
        "74 pose values",
    ),
    "truncated": (json.dumps(_valid_doc()).encode()[:120], "not valid JSON \\(file truncated"),
    "non_utf8": (b'{"people": [], "version": "\xff\xfe1.3"}', "not UTF-8"),
    "top_level_list": (b"[1, 2, 3]", "not a JSON object"),
    "non_numeric": (
        json.dumps({"people": [{"pose_keypoints_2d": ["a"] * 75}]}).encode(),
        "not all numbers",
    ),
    "no_keypoints": (
        json.dumps({"people": [{"person_id": [-1]}]}).encode(),
        "no 'pose_keypoints_2d'",
    ),
    "bad_person_id": (
        json.dumps({"people": [{"person_id": "x", "pose_keypoints_2d": [0] * 75}]}).encode(),
        "person_id",
    ),
}


@pytest.mark.parametrize("case", sorted(MALFORMED))
def test_malformed_file_names_the_file(tmp_path: Path, case: str) -> None:
    data, message = MALFORMED[case]
    _write(tmp_path, 0, [_person(25, 0)])
    bad = tmp_path / "video_000000000001_keypoints.json"
    bad.write_bytes(data)
    _write(tmp_path, 2, [_person(25, 2)])
    with pytest.raises(InputError, match=message) as info:
        read_openpose_folder(tmp_path)
    text = str(info.value)
    assert text.startswith(str(bad) + ": ")
    assert "\n" not in text


def test_count_differing_from_first_file_is_refused(tmp_path: Path) -> None:
    _write(tmp_path, 0, [_person(25, 0)])
    bad = _write(tmp_path, 1, [_person(18, 1)])
    with pytest.raises(InputError, match="54 pose values, expected 75") as info:
        read_openpose_folder(tmp_path)
    assert str(bad) in str(info.value)


def test_folder_problems(tmp_path: Path) -> None:
    with pytest.raises(InputError, match="not a folder"):
        read_openpose_folder(tmp_path / "absent")
    (tmp_path / "notes.txt").write_text("x")
    with pytest.raises(InputError, match="no \\*_keypoints.json files"):
        read_openpose_folder(tmp_path)
    (tmp_path / "video_keypoints.json").write_text("{}")
    with pytest.raises(InputError, match="no frame number"):
        read_openpose_folder(tmp_path)


def test_body_model_by_majority_names_the_odd_file(tmp_path: Path) -> None:
    odd = _write(tmp_path, 0, [_person(18, 0)])  # the first file is the odd one out
    _write(tmp_path, 1, [_person(25, 1)])
    _write(tmp_path, 2, [_person(25, 2)])
    with pytest.raises(InputError, match="54 pose values, expected 75") as info:
        read_openpose_folder(tmp_path)
    assert str(info.value).startswith(str(odd))


def test_bad_files_become_missing_frames_when_handled(tmp_path: Path) -> None:
    _write(tmp_path, 0, [_person(25, 0)])
    truncated = tmp_path / "video_000000000001_keypoints.json"
    truncated.write_text('{"version": 1.3, "people": [')
    odd = _write(tmp_path, 2, [_person(18, 2)])
    _write(tmp_path, 3, [_person(25, 3)])
    bad: list[tuple[Path, str]] = []
    frames = read_openpose_folder(tmp_path, on_bad_file=lambda p, e: bad.append((p, e)))
    assert frames.skeleton is BODY_25 and frames.n_frames == 4
    assert frames.present.tolist() == [True, False, False, True]
    assert frames.n_people.tolist() == [1, 0, 0, 1] and frames.keypoints.shape == (2, 25, 3)
    assert [p for p, _ in bad] == [truncated, odd]
    assert "truncated" in bad[0][1] and "54 pose values" in bad[1][1]


def test_keypoint_file_prefix() -> None:
    assert keypoint_file_prefix("short_video_000000000012_keypoints.json") == "short_video"
    assert keypoint_file_prefix("000000000012_keypoints.json") == ""
    assert keypoint_file_prefix("notes.txt") is None
