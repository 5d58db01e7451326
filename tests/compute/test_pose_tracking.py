"""Choosing and following one dancer: crossing paths, id swaps, jumps, selection, gap filling."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from dancedata.compute.pose_tracking import (
    box_iou,
    fill_gaps,
    fill_tracked_gaps,
    track_dancer,
    track_openpose,
)
from dancedata.errors import InputError
from dancedata.io.openpose import read_openpose_folder

J = 25
TEMPLATE = np.random.default_rng(7).uniform(-0.5, 0.5, (J, 2)) * [60.0, 180.0]


def body(cx: float, cy: float, scale: float = 1.0) -> np.ndarray:
    """(J, 3) keypoints of a synthetic person centred at (cx, cy) pixels, confidence 0.9."""
    out = np.empty((J, 3))
    out[:, :2] = TEMPLATE * scale + [cx, cy]
    out[:, 2] = 0.9
    return out


def ragged(frames: list[list[np.ndarray]], ids: list[list[int]] | None = None, seed: int = 0):
    """Per-frame lists of people → (keypoints, person_ids, offsets), rows shuffled per frame."""
    rng = np.random.default_rng(seed)
    rows, pid, counts = [], [], []
    for f, people in enumerate(frames):
        order = rng.permutation(len(people))
        rows += [people[k] for k in order]
        pid += [ids[f][k] if ids else -1 for k in order]
        counts.append(len(people))
    offsets = np.concatenate([[0], np.cumsum(counts)])
    return np.array(rows), np.array(pid), offsets


def crossing(n: int = 40, speed: float = 15.0, drop_seed: int | None = 1):
    """A walks right, B walks left; they pass between frames 19 and 20 with the same body."""
    rng = np.random.default_rng(drop_seed or 0)
    a_true, b_true, frames = [], [], []
    for f in range(n):
        a = body(100 + speed * f + speed / 2, 300, 1.1)
        b = body(700 - speed * f - speed / 2, 306, 1.0)
        if drop_seed is not None:  # three undetected joints per person per frame, as OpenPose
            a[rng.choice(J, 3, replace=False)] = 0.0
            b[rng.choice(J, 3, replace=False)] = 0.0
        a_true.append(a)
        b_true.append(b)
        frames.append([a, b])
    return np.array(a_true), np.array(b_true), frames


def assert_follows(pose, truth: np.ndarray, frames: range | list[int]) -> None:
    for f in frames:
        seen = truth[f, :, 2] > 0
        np.testing.assert_array_equal(pose.mask[f], seen)
        np.testing.assert_allclose(pose.coords[f][seen], truth[f][seen, :2], atol=1e-3)
        assert np.isnan(pose.coords[f][~seen]).all()
        np.testing.assert_allclose(pose.conf[f], truth[f, :, 2], atol=1e-6)


# ----------------------------------------------------------------------------- identity


def test_crossing_paths_without_ids_keeps_identity() -> None:
    a, b, frames = crossing()
    # The case is hard: just after the crossing, B's body is nearer A's last position than A is,
    # so following the nearest box would swap the dancers.
    ca = lambda t: t[..., :2].mean(axis=-2)  # noqa: E731
    assert np.linalg.norm(ca(b[20]) - ca(a[19])) < np.linalg.norm(ca(a[20]) - ca(a[19]))
    pose = track_dancer(*ragged(frames))
    assert pose.method == "bbox"
    assert pose.n_labels == 2
    assert pose.identity_switches == ()
    assert pose.selection == "area"  # A is 1.1× larger, so the default picks A
    assert_follows(pose, a, range(len(frames)))


def test_crossing_paths_other_person_by_tracklet_index() -> None:
    a, b, frames = crossing()
    # Tracklets are numbered left to right on first appearance: A is 0, B is 1.
    pose = track_dancer(*ragged(frames), person=1)
    assert pose.selection == "override" and pose.chosen == 1
    assert_follows(pose, b, range(len(frames)))


def test_forced_id_swap_is_counted_as_identity_switch() -> None:
    a, b, frames = crossing(drop_seed=None)
    swap = 8  # far from the crossing: A near x=230, B near x=570
    ids = [[0, 1] if f < swap else [1, 0] for f in range(len(frames))]
    for person in (0, 1):
        pose = track_dancer(*ragged(frames, ids), person=person)
        assert pose.method == "person_id"
        assert pose.identity_switches == (swap,)
        assert pose.report()["identity_switches"] == 1
    # Following id 0 (trusted) jumps from A's body to B's at the swap.
    pose = track_dancer(*ragged(frames, ids), person=0)
    assert_follows(pose, a, range(swap))
    assert_follows(pose, b, range(swap, len(frames)))


def test_consistent_ids_through_a_crossing_have_no_switch() -> None:
    a, b, frames = crossing()
    ids = [[0, 1]] * len(frames)
    pose = track_dancer(*ragged(frames, ids), person=1)
    assert pose.method == "person_id" and pose.identity_switches == ()
    assert_follows(pose, b, range(len(frames)))
    # Ignoring the ids gives the same answer by continuity alone.
    assert track_dancer(*ragged(frames, ids), by="bbox", person=1).identity_switches == ()


def test_same_id_back_after_a_long_absence_is_not_a_switch() -> None:
    # Lost for 15 frames (more than max_lost = 10): the tracker starts a new tracklet, but the
    # id's old body is gone, so nothing shows the id moved to someone else.
    frames = [[] if 10 <= f < 25 else [body(100 + 4 * f, 300), body(600, 300)] for f in range(40)]
    ids = [[] if 10 <= f < 25 else [3, 8] for f in range(40)]
    pose = track_dancer(*ragged(frames, ids), person=3)
    assert pose.method == "person_id" and pose.identity_switches == ()
    assert (pose.source_row >= 0).sum() == 25


def test_jump_beyond_the_gate_is_relinked_and_counted() -> None:
    frames = [[body(100 + 5 * f, 300)] if f < 15 else [body(900 + 5 * f, 300)] for f in range(30)]
    pose = track_dancer(*ragged(frames))
    assert pose.n_labels == 2
    assert pose.identity_switches == (15,)
    assert (pose.source_row >= 0).all()
    assert pose.label.tolist() == [0] * 15 + [1] * 15
    # Without re-linking the dancer is lost after the jump.
    alone = track_dancer(*ragged(frames), relink_gap=0)
    assert alone.identity_switches == () and (alone.source_row >= 0).sum() == 15


def test_short_absence_keeps_one_tracklet_and_fills_exactly() -> None:
    truth = [body(100 + 10 * f, 300) for f in range(20)]
    frames = [[] if 8 <= f <= 10 else [truth[f]] for f in range(20)]
    pose = track_dancer(*ragged(frames))
    assert pose.n_labels == 1 and pose.identity_switches == ()
    assert not pose.mask[8:11].any() and np.isnan(pose.coords[8:11]).all()
    filled = fill_tracked_gaps(pose, max_gap=3)
    assert filled.filled[8:11].all() and filled.filled.sum() == 3 * J
    # Constant velocity: linear interpolation recovers the truth.
    np.testing.assert_allclose(filled.coords, np.array(truth)[..., :2], atol=1e-3)
    assert (filled.conf[8:11] == 0).all()
    assert not fill_tracked_gaps(pose, max_gap=2).filled.any()


# ----------------------------------------------------------------------------- selection


def test_default_selection_area_versus_frames() -> None:
    med = [body(100, 300, 1.0) for _ in range(40)]
    big = [body(400, 300, 1.5) for _ in range(40)]
    huge = [body(700, 300, 3.0) for _ in range(40)]
    frames = []
    for f in range(40):
        people = [med[f]]
        if f < 30:
            people.append(big[f])  # 75 % of the frames
        if f < 2:
            people.append(huge[f])  # a large false detection in 2 frames
        frames.append(people)
    by_area = track_dancer(*ragged(frames))
    assert_follows(by_area, np.array(big), range(30))
    assert (by_area.source_row[30:] == -1).all()
    by_frames = track_dancer(*ragged(frames), select="frames")
    assert_follows(by_frames, np.array(med), range(40))
    # Without the coverage floor the 2-frame false detection would win on area.
    assert track_dancer(*ragged(frames), min_coverage=0.0).chosen == 2
    with pytest.raises(InputError, match="tracklet 5 not found; present: \\[0, 1, 2\\]"):
        track_dancer(*ragged(frames), person=5)


def test_missing_people_and_zero_confidence_joints_become_nan() -> None:
    person = body(200, 300)
    person[3] = 0.0
    frames = [[person], [], [person]]
    pose = track_dancer(*ragged(frames))
    assert pose.coords.shape == (3, J, 2) and pose.coords.dtype == np.float32
    assert pose.mask[0].sum() == J - 1 and not pose.mask[0, 3]
    assert not pose.mask[1].any() and (pose.conf[1] == 0).all()
    assert pose.source_row.tolist() == [0, -1, 1]


def test_nobody_detected_is_an_input_error() -> None:
    empty = body(0, 0)
    empty[:, 2] = 0.0
    with pytest.raises(InputError, match="no person with any detected joint"):
        track_dancer(*ragged([[empty], [empty]]))


def test_box_iou_known_values() -> None:
    a = np.array([[0, 0, 10, 10]], float)
    b = np.array([[5, 0, 15, 10], [20, 20, 30, 30], [0, 0, 10, 10]], float)
    np.testing.assert_allclose(box_iou(a, b), [[50 / 150, 0.0, 1.0]])


# ----------------------------------------------------------------------------- gap filling


def _reference_fill(values: np.ndarray, mask: np.ndarray, max_gap: int) -> np.ndarray:
    out = np.where(mask[..., None], values, np.nan)
    n = values.shape[0]
    for j in range(values.shape[1]):
        known = np.flatnonzero(mask[:, j])
        for f in range(n):
            if mask[f, j]:
                continue
            before, after = known[known < f], known[known > f]
            if before.size and after.size and after[0] - before[-1] - 1 <= max_gap:
                a, b = before[-1], after[0]
                for d in range(values.shape[2]):
                    out[f, j, d] = np.interp(f, [a, b], [values[a, j, d], values[b, j, d]])
    return out


@settings(max_examples=60, deadline=None)
@given(
    mask=st.lists(st.lists(st.booleans(), min_size=2, max_size=2), min_size=1, max_size=25),
    max_gap=st.integers(0, 6),
    seed=st.integers(0, 1000),
)
def test_fill_gaps_matches_per_frame_interpolation(mask, max_gap, seed) -> None:
    m = np.array(mask, dtype=bool)
    values = np.random.default_rng(seed).normal(size=m.shape + (3,))
    coords, new_mask, filled = fill_gaps(np.where(m[..., None], values, np.nan), m, max_gap)
    reference = _reference_fill(values, m, max_gap)
    np.testing.assert_allclose(coords, reference, rtol=1e-12, atol=1e-12)
    np.testing.assert_array_equal(new_mask, np.isfinite(reference).all(-1))
    np.testing.assert_array_equal(filled, new_mask & ~m)


# ----------------------------------------------------------------------------- real data


@pytest.mark.real_data
def test_raga_3people_three_stable_seated_people(real_data: Path) -> None:
    frames = read_openpose_folder(real_data / "openpose" / "raga_example_3people" / "output_json")
    pose = track_openpose(frames)
    assert pose.method == "bbox" and pose.n_labels == 3 and pose.identity_switches == ()
    # Independent reference: the performers are seated side by side, so ordering each frame's
    # people by the x of their detected joints identifies them.
    kp = frames.keypoints.reshape(125, 3, 25, 3)
    x = np.where(kp[..., 2] > 0, kp[..., 0], np.nan)
    order = np.argsort(np.nanmean(x, axis=-1), axis=1)
    for k in range(3):
        followed = track_openpose(frames, person=k)
        assert (followed.source_row >= 0).all()
        rank = [
            int(np.flatnonzero(order[f] == followed.source_row[f] - 3 * f)[0]) for f in range(125)
        ]
        assert rank == [k] * 125  # tracklet k is the k-th from the left in every frame
    # Default = largest mean box area, computed here from the left-to-right reference.
    y = np.where(kp[..., 2] > 0, kp[..., 1], np.nan)
    area = (np.nanmax(x, -1) - np.nanmin(x, -1)) * (np.nanmax(y, -1) - np.nanmin(y, -1))
    area_by_rank = np.take_along_axis(area, order, axis=1).mean(axis=0)
    assert pose.chosen == int(np.argmax(area_by_rank))


@pytest.mark.real_data
def test_raga_1person_masks_follow_confidence(real_data: Path) -> None:
    frames = read_openpose_folder(real_data / "openpose" / "raga_example_1person" / "output_json")
    pose = track_openpose(frames)
    raw = frames.keypoints
    np.testing.assert_array_equal(pose.mask, raw[..., 2] > 0)
    np.testing.assert_array_equal(pose.coords[pose.mask], raw[..., :2][pose.mask])
    np.testing.assert_array_equal(pose.conf, raw[..., 2])
    report = pose.report()
    assert report["frames_with_dancer"] == 125 and report["identity_switches"] == 0
