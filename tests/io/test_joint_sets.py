"""Joint sets of 3-d pose lifters (H36M-17, SPIN-24, HMR-19) in joints CSVs: recognised by name in
any of their spellings and column order, stored with their own skeleton (a tree with one root),
named in headerless CSVs by --skeleton, and enough for rotations_from_positions."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from dancedata.ingest.video import ingest_video
from dancedata.ingest.video.poses import SKELETONS, skeleton_for_joints
from dancedata.io.joint_sets import H36M_17, HMR_19, LIFTER_SETS, SPIN_24
from dancedata.store.reader import _VersionReader
from tests.ingest.test_ingest_video import options


@pytest.mark.parametrize("joint_set", list(LIFTER_SETS.values()), ids=list(LIFTER_SETS))
def test_every_set_is_a_tree_with_one_root(joint_set):
    parents = joint_set.parents
    assert len(parents) == len(joint_set.joints)
    assert sum(p < 0 for p in parents) == 1
    for start in range(len(parents)):  # every joint reaches the root without a cycle
        seen, j = set(), start
        while j >= 0:
            assert j not in seen
            seen.add(j)
            j = parents[j]
    for alias in joint_set.aliases:
        assert len(alias) == len(joint_set.joints)


@pytest.mark.parametrize(
    "spelling,expected",
    [
        (H36M_17.joints, "h36m17"),
        (H36M_17.aliases[0], "h36m17"),
        (SPIN_24.joints, "spin24"),
        (HMR_19.joints, "hmr19"),
        (HMR_19.aliases[0], "hmr19"),
        (tuple(n.upper().replace(" ", "_") for n in SPIN_24.joints), "spin24"),
    ],
)
def test_names_match_in_any_order_and_spelling(spelling, expected):
    shuffled = tuple(reversed(spelling))
    skeleton, order = skeleton_for_joints(shuffled)
    assert skeleton["name"] == expected
    # column `order[k]` of the CSV holds the set's joint k
    canonical = LIFTER_SETS[expected]
    assert len(order) == len(canonical.joints) and sorted(order) == list(range(len(order)))
    from dancedata.io.joint_sets import normalise_name

    wanted = [normalise_name(j) for j in canonical.spellings()[0]]
    names = [normalise_name(shuffled[i]) for i in order]
    assert names == wanted or any(
        names == [normalise_name(j) for j in a] for a in canonical.aliases
    )


def test_unknown_names_stay_custom():
    skeleton, order = skeleton_for_joints(("a", "b"))
    assert skeleton["name"] == "custom" and order == [0, 1]


def _write(path: Path, names: tuple[str, ...], frames: int = 4, header: bool = True) -> np.ndarray:
    rng = np.random.default_rng(len(names))
    values = rng.normal(0, 0.3, (frames, len(names), 3))
    lines = []
    if header:
        lines.append(",".join(["frame"] + [f"{n}_{a}" for n in names for a in "xyz"]))
    for f in range(frames):
        row = [str(f)] if header else []
        lines.append(",".join(row + [f"{v:.6f}" for v in values[f].reshape(-1)]))
    path.write_text("\n".join(lines) + "\n")
    return values


@pytest.mark.parametrize("name", list(LIFTER_SETS))
def test_ingest_stores_the_lifter_skeleton(tmp_path, name):
    joint_set = LIFTER_SETS[name]
    csv = tmp_path / "take.csv"
    values = _write(csv, joint_set.spellings()[-1])
    store = tmp_path / "store"
    ingest_video(store, [], options(joints_csv=csv, fps=30.0))
    reader = _VersionReader(store)
    skeleton = reader.group_attrs("motion")["skeleton"]
    assert reader.array("motion/positions").attrs["skeleton"] == skeleton
    assert skeleton["name"] == name and skeleton["parents"] == list(joint_set.parents)
    np.testing.assert_allclose(reader.array("motion/positions")[:], values, atol=1e-6)


def test_headerless_csv_takes_the_named_set(tmp_path):
    csv = tmp_path / "plain.csv"
    values = _write(csv, H36M_17.joints, header=False)
    store = tmp_path / "store"
    ingest_video(store, [], options(joints_csv=csv, fps=30.0, skeleton="h36m17"))
    np.testing.assert_allclose(
        _VersionReader(store).array("motion/positions")[:], values, atol=1e-6
    )
    assert {"body25", "coco18", "h36m17", "spin24", "hmr19"} <= set(SKELETONS)
