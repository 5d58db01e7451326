"""3-d joints CSV reader: header styles, headerless mapping, frame/time columns, bad files."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from dancedata.errors import InputError
from dancedata.io.joints_csv import read_joints_csv

NAMES = ["pelvis", "l_knee", "r.hand"]  # a dot inside a joint name must survive ".x" splitting


def _data(n: int = 6, seed: int = 3) -> np.ndarray:
    return np.random.default_rng(seed).normal(size=(n, len(NAMES), 3))


def _cells(values: np.ndarray) -> list[list[str]]:
    return [[repr(float(v)) for v in row.ravel()] for row in values]


def test_underscore_header_with_frame_column(tmp_path: Path) -> None:
    values = _data()
    header = ["frame"] + [f"{j}_{a}" for j in NAMES for a in "xyz"]
    lines = [",".join(header)] + [
        ",".join([str(f)] + cells) for f, cells in enumerate(_cells(values))
    ]
    path = tmp_path / "joints.csv"
    path.write_text("\n".join(lines) + "\n")
    out = read_joints_csv(path)
    assert out.joints == tuple(NAMES)
    np.testing.assert_array_equal(out.positions, values)  # repr round-trips exactly
    np.testing.assert_array_equal(out.frames, np.arange(6))
    assert out.present.all() and out.times is None


def test_dot_header_semicolons_uppercase_axes_and_time(tmp_path: Path) -> None:
    values = _data(4)
    header = ["Time"] + [f"{j}.{a.upper()}" for j in NAMES for a in "xyz"]
    times = [0.0, 0.04, 0.08, 0.12]
    lines = [";".join(header)] + [
        ";".join([str(t)] + c) for t, c in zip(times, _cells(values), strict=True)
    ]
    path = tmp_path / "joints.csv"
    path.write_text("\ufeff" + "\r\n".join(lines))  # BOM and CRLF, as spreadsheets write
    out = read_joints_csv(path)
    assert out.joints == tuple(NAMES)
    np.testing.assert_array_equal(out.positions, values)
    np.testing.assert_array_equal(out.times, times)
    assert out.frames is None


def test_columns_in_any_order_are_grouped_by_joint(tmp_path: Path) -> None:
    path = tmp_path / "j.csv"
    path.write_text("a_z,b_x,a_x,b_z,a_y,b_y\n3,4,1,6,2,5\n")
    out = read_joints_csv(path)
    assert out.joints == ("a", "b")
    np.testing.assert_array_equal(out.positions[0], [[1, 2, 3], [4, 5, 6]])


def test_headerless_with_joint_list(tmp_path: Path) -> None:
    values = _data()
    path = tmp_path / "lifter.csv"
    path.write_text("\n".join(",".join(c) for c in _cells(values)))
    out = read_joints_csv(path, joints=NAMES)
    np.testing.assert_array_equal(out.positions, values)
    assert out.frames is None and out.n_frames == 6


def test_headerless_tab_with_one_based_frames_and_a_gap(tmp_path: Path) -> None:
    values = _data(3)
    numbers = [1, 2, 5]  # 1-based, frames 3 and 4 missing
    path = tmp_path / "lifter.tsv"
    path.write_text(
        "\n".join("\t".join([str(n)] + c) for n, c in zip(numbers, _cells(values), strict=True))
    )
    out = read_joints_csv(path, joints=NAMES, index_column="frame", frame_base=1)
    assert out.n_frames == 5
    assert out.present.tolist() == [True, True, False, False, True]
    np.testing.assert_array_equal(out.positions[[0, 1, 4]], values)
    assert np.isnan(out.positions[2:4]).all()
    np.testing.assert_array_equal(out.frames, [1, 2, 3, 4, 5])


def test_pandas_index_column_is_the_frame(tmp_path: Path) -> None:
    path = tmp_path / "j.csv"
    path.write_text(",a_x,a_y,a_z\n0,1,2,3\n2,4,5,6\n")  # DataFrame.to_csv with its index
    out = read_joints_csv(path)
    assert out.present.tolist() == [True, False, True]
    np.testing.assert_array_equal(out.positions[2, 0], [4, 5, 6])


def test_empty_and_nan_cells_are_nan(tmp_path: Path) -> None:
    path = tmp_path / "j.csv"
    path.write_text("a_x,a_y,a_z\n1,,nan\n")
    out = read_joints_csv(path)
    assert out.positions[0, 0, 0] == 1 and np.isnan(out.positions[0, 0, 1:]).all()


def test_ignored_extra_column(tmp_path: Path) -> None:
    path = tmp_path / "j.csv"
    path.write_text("score,a_x,a_y,a_z\n0.5,1,2,3\n")
    with pytest.raises(InputError, match="column 1 'score'"):
        read_joints_csv(path)
    np.testing.assert_array_equal(read_joints_csv(path, ignore=("score",)).positions, [[[1, 2, 3]]])


BAD = {
    "missing_axis": ("a_x,a_y,b_x,b_y,b_z\n1,2,3,4,5\n", {}, "joint 'a' has no z column"),
    "unknown_column": ("a_x,a_y,a_z,foo\n1,2,3,4\n", {}, "column 4 'foo'"),
    "ragged_row": ("a_x,a_y,a_z\n1,2,3\n1,2\n", {}, "line 3 has 2 columns, expected 3"),
    "not_a_number": ("a_x,a_y,a_z\n1,2,3\n1,two,3\n", {}, "line 3, column a_y: 'two'"),
    "headerless_no_joints": ("1,2,3\n", {}, "pass the joint names"),
    "headerless_wrong_width": ("1,2,3,4\n", {"joints": ["a"]}, "line 1 has 4 columns"),
    "duplicate_frame": ("frame,a_x,a_y,a_z\n0,1,2,3\n0,1,2,3\n", {}, "frame 0 appears more"),
    "fractional_frame": ("frame,a_x,a_y,a_z\n0.5,1,2,3\n", {}, "not whole numbers"),
    "time_not_increasing": ("t,a_x,a_y,a_z\n1,1,2,3\n0.5,1,2,3\n", {}, "not strictly increasing"),
    "header_only": ("a_x,a_y,a_z\n", {}, "no data rows"),
    "empty": ("\n\n", {}, "empty CSV"),
    "duplicate_column": ("a_x,a_y,a_z,a.x\n1,2,3,4\n", {}, "'a.x' appears twice"),
    "joint_mismatch": ("a_x,a_y,a_z\n1,2,3\n", {"joints": ["b"]}, "differ from the joints given"),
}


@pytest.mark.parametrize("case", sorted(BAD))
def test_bad_csv_names_the_file(tmp_path: Path, case: str) -> None:
    text, kwargs, message = BAD[case]
    path = tmp_path / f"{case}.csv"
    path.write_text(text)
    with pytest.raises(InputError, match=message) as info:
        read_joints_csv(path, **kwargs)
    assert str(info.value).startswith(str(path) + ": ")


def test_non_utf8_and_missing_file(tmp_path: Path) -> None:
    path = tmp_path / "latin1.csv"
    path.write_bytes("gelenk_ä_x,a_y,a_z\n1,2,3\n".encode("latin-1"))
    with pytest.raises(InputError, match="not UTF-8"):
        read_joints_csv(path)
    with pytest.raises(InputError, match="file not found"):
        read_joints_csv(tmp_path / "absent.csv")


def test_headerless_auto_index_column_by_width(tmp_path: Path) -> None:
    values = _data(3)
    plain = tmp_path / "plain.csv"
    plain.write_text("\n".join(",".join(c) for c in _cells(values)))
    out = read_joints_csv(plain, joints=NAMES, index_column="auto")
    assert out.frames is None and out.n_frames == 3
    np.testing.assert_array_equal(out.positions, values)
    framed = tmp_path / "framed.csv"
    framed.write_text("\n".join(",".join([str(2 * f)] + c) for f, c in enumerate(_cells(values))))
    out = read_joints_csv(framed, joints=NAMES, index_column="auto")
    assert out.n_frames == 5 and out.present.tolist() == [True, False, True, False, True]
    odd = tmp_path / "odd.csv"
    odd.write_text("1,2,3,4,5\n")
    with pytest.raises(InputError, match="5 columns; 3 joints need 9 .* or 10") as info:
        read_joints_csv(odd, joints=NAMES, index_column="auto")
    assert str(odd) in str(info.value)
