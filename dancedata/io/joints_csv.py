"""Read 3-d joints from a pose lifter (HMR-style) written as CSV: one row per frame.

Column mapping (documented contract for ``dancedata ingest video --poses``):

* **With a header** (the first row has a cell that is not a number): coordinate columns are named
  ``<joint>_x, <joint>_y, <joint>_z`` or ``<joint>.x, <joint>.y, <joint>.z`` (axis letter in any
  case). Joints are taken in the order their first column appears; every joint needs all three
  axes. A frame column is recognised by name (``frame``, ``frame_index``, ``frame_idx``,
  ``frame_id``, ``index``, ``idx``, or a nameless first column as pandas writes its index), a
  time column in seconds by name (``time``, ``time_s``, ``timestamp``, ``t``); other columns
  are an error, so that a typo is never silently dropped, unless listed in ``ignore``.
* **Without a header**: pass ``joints`` (names, in column order). Each row is then
  ``x0, y0, z0, x1, y1, z1, ...``, optionally preceded by one frame or time column
  (``index_column="frame"`` / ``"time"``; ``"auto"`` takes a first column as the frame number
  when the first row has ``3 J + 1`` cells, none when it has ``3 J``).

Frames: with a frame column, rows are placed at their frame number minus ``frame_base`` (so
gaps become missing frames, NaN, ``present`` False, exactly like OpenPose file numbering); without
one, row r is frame r. Empty cells and ``nan`` are NaN. Units are whatever the lifter wrote
(usually metres, sometimes millimetres or normalised); they are not guessed.
Delimiter: ``,``, ``;`` or tab, detected from the first line unless given. At most
:data:`MAX_JOINTS` joints; frame numbers within :mod:`dancedata.io.frame_limits`.
"""

from __future__ import annotations

import csv
import io
import math
import re
from dataclasses import dataclass
from pathlib import Path
from typing import Literal

import numpy as np

from dancedata.errors import InputError
from dancedata.io.frame_limits import check_frame_span

FRAME_NAMES = ("frame", "frame_index", "frame_idx", "frame_id", "index", "idx")
TIME_NAMES = ("time", "time_s", "timestamp", "t")
_COORD_RE = re.compile(r"^(?P<joint>.+)[_.](?P<axis>[xyzXYZ])$")
_AXES = "xyz"
MAX_JOINTS = 1000  # SMPL-X has 127 joints, BODY_135 135; a header with more is not a skeleton


@dataclass(frozen=True)
class JointsCSV:
    """3-d joints read from a CSV.

    Attributes:
        path: the file read.
        positions: (F, J, 3) float64, the lifter's units; NaN where missing.
        joints: J joint names.
        present: (F,) bool, False for frames absent from the file (gaps in the frame column).
        frames: (F,) int64 frame numbers as written (``frame_base`` added back), or None.
        times: (F,) float64 seconds from a time column (NaN for absent frames), or None.
    """

    path: Path
    positions: np.ndarray
    joints: tuple[str, ...]
    present: np.ndarray
    frames: np.ndarray | None
    times: np.ndarray | None

    @property
    def n_frames(self) -> int:
        return int(self.positions.shape[0])


def _to_float(cell: str, path: Path, line: int, column: str) -> float:
    text = cell.strip()
    if text == "" or text.lower() in ("nan", "na", "null"):
        return math.nan
    try:
        return float(text)
    except ValueError:
        raise InputError(f"line {line}, column {column}: {cell!r} is not a number", path) from None


def _is_number(cell: str) -> bool:
    text = cell.strip()
    if text == "" or text.lower() in ("nan", "na", "null"):
        return True
    try:
        float(text)
    except ValueError:
        return False
    return True


def _read_rows(path: Path, delimiter: str | None) -> list[list[str]]:
    try:
        data = path.read_bytes()
    except FileNotFoundError:
        raise InputError("file not found", path) from None
    except OSError as exc:
        raise InputError(f"cannot read: {exc.strerror}", path) from None
    try:
        text = data.decode("utf-8-sig")
    except UnicodeDecodeError as exc:
        raise InputError(f"not UTF-8 text (byte {exc.start})", path) from None
    lines = text.splitlines()
    if not any(line.strip() for line in lines):
        raise InputError("empty CSV", path)
    if delimiter is None:
        first = next(line for line in lines if line.strip())
        delimiter = max(",;\t", key=first.count)
    return [row for row in csv.reader(io.StringIO(text), delimiter=delimiter)]


def _header_columns(
    header: list[str], path: Path, ignore: tuple[str, ...]
) -> tuple[list[str], dict[tuple[str, str], int], int | None, int | None]:
    joints: list[str] = []
    seen: set[str] = set()  # a set beside the ordered list: the check stays linear
    coord: dict[tuple[str, str], int] = {}
    frame_col = time_col = None
    for c, raw in enumerate(header):
        name = raw.strip()
        low = name.lower()
        if name in ignore:
            continue
        if (low in FRAME_NAMES or (c == 0 and low in ("", "unnamed: 0"))) and frame_col is None:
            frame_col = c
            continue
        if low in TIME_NAMES and time_col is None:
            time_col = c
            continue
        match = _COORD_RE.match(name)
        if match is None:
            raise InputError(
                f"column {c + 1} {name!r} is not <joint>_x/_y/_z, <joint>.x/.y/.z, a frame or a "
                "time column (list it in ignore to skip it)",
                path,
            )
        joint, axis = match.group("joint"), match.group("axis").lower()
        if (joint, axis) in coord:
            raise InputError(f"column {name!r} appears twice", path)
        if joint not in seen:
            if len(joints) >= MAX_JOINTS:
                raise InputError(f"more than {MAX_JOINTS} joints in the header", path)
            seen.add(joint)
            joints.append(joint)
        coord[(joint, axis)] = c
    if not joints:
        raise InputError("no <joint>_x/_y/_z columns in the header", path)
    for joint in joints:
        missing = [a for a in _AXES if (joint, a) not in coord]
        if missing:
            raise InputError(f"joint {joint!r} has no {'/'.join(missing)} column", path)
    return joints, coord, frame_col, time_col


def _auto_index_column(width: int, n_joints: int, path: Path) -> Literal["frame"] | None:
    if width == 3 * n_joints:
        return None
    if width == 3 * n_joints + 1:
        return "frame"
    raise InputError(
        f"the first row has {width} columns; {n_joints} joints need {3 * n_joints} "
        f"(x, y, z each) or {3 * n_joints + 1} (after a frame column)",
        path,
    )


def read_joints_csv(
    path: str | Path,
    joints: list[str] | tuple[str, ...] | None = None,
    index_column: Literal["frame", "time", "auto"] | None = None,
    frame_base: int = 0,
    delimiter: str | None = None,
    ignore: tuple[str, ...] = (),
) -> JointsCSV:
    """Read a lifter's 3-d joints CSV (module docstring: the column mapping).

    Args:
        path: the CSV file.
        joints: joint names for a headerless file, in column order (ignored with a header,
            except that a header naming other joints is an error when both are given).
        index_column: headerless only: the first column is a frame number or a time (seconds);
            "auto": a frame number exactly when the first row has 3 × len(joints) + 1 cells.
        frame_base: the frame number of the video's first frame in the frame column (0 or 1).
        delimiter: force a delimiter instead of detecting it.
        ignore: header names of extra columns to skip.

    Raises:
        InputError: naming the file (and line/column), for a missing, empty, non-UTF-8 file,
            unknown or incomplete columns, ragged rows, non-numeric cells, or a frame column
            that is not whole numbers, repeats a frame or goes below ``frame_base``.
    """
    path = Path(path)
    rows = _read_rows(path, delimiter)
    first_line = next(i for i, row in enumerate(rows) if any(cell.strip() for cell in row))
    header = rows[first_line]
    has_header = not all(_is_number(cell) for cell in header)
    frame_col = time_col = None
    if has_header:
        names, coord, frame_col, time_col = _header_columns(header, path, ignore)
        if joints is not None and list(joints) != names:
            raise InputError(
                f"header joints {names} differ from the joints given {list(joints)}", path
            )
        body = rows[first_line + 1 :]
        body_start = first_line + 2
        width = len(header)
    else:
        if joints is None:
            raise InputError(
                "no header row: pass the joint names (joints=...) for its columns", path
            )
        names = list(joints)
        if index_column == "auto":
            index_column = _auto_index_column(len(header), len(names), path)
        lead = 1 if index_column is not None else 0
        if index_column == "frame":
            frame_col = 0
        elif index_column == "time":
            time_col = 0
        elif index_column is not None:
            raise InputError(
                f"index_column must be 'frame', 'time' or None, not {index_column!r}", path
            )
        coord = {(j, a): lead + 3 * k + i for k, j in enumerate(names) for i, a in enumerate(_AXES)}
        body = rows[first_line:]
        body_start = first_line + 1
        width = lead + 3 * len(names)
    colnames = {c: f"{j}_{a}" for (j, a), c in coord.items()}
    values: list[list[float]] = []
    frame_numbers: list[float] = []
    times: list[float] = []
    for k, row in enumerate(body):
        line = body_start + k
        if not any(cell.strip() for cell in row):
            continue
        if len(row) != width:
            raise InputError(f"line {line} has {len(row)} columns, expected {width}", path)
        values.append(
            [
                _to_float(row[coord[(j, a)]], path, line, colnames[coord[(j, a)]])
                for j in names
                for a in _AXES
            ]
        )
        if frame_col is not None:
            frame_numbers.append(_to_float(row[frame_col], path, line, "frame"))
        if time_col is not None:
            times.append(_to_float(row[time_col], path, line, "time"))
    if not values:
        raise InputError("no data rows", path)
    data = np.asarray(values, dtype=np.float64).reshape(len(values), len(names), 3)
    time_arr = np.asarray(times, dtype=np.float64) if time_col is not None else None
    if time_arr is not None and not (np.diff(time_arr) > 0).all():
        raise InputError("time column is not strictly increasing", path)
    if frame_col is None:
        return JointsCSV(path, data, tuple(names), np.ones(len(values), bool), None, time_arr)

    numbers = np.asarray(frame_numbers)
    if not np.isfinite(numbers).all() or (numbers != np.round(numbers)).any():
        raise InputError("frame column holds values that are not whole numbers", path)
    index = numbers.astype(np.int64) - frame_base
    if (index < 0).any():
        raise InputError(
            f"frame number {int(numbers.min())} is below frame_base {frame_base}", path
        )
    if np.unique(index).size != index.size:
        dup = int(np.flatnonzero(np.bincount(index) > 1)[0]) + frame_base
        raise InputError(f"frame {dup} appears more than once", path)
    check_frame_span(int(index.max()), len(index), path, "rows")
    n_frames = int(index.max()) + 1
    positions = np.full((n_frames, len(names), 3), np.nan)
    positions[index] = data
    present = np.zeros(n_frames, bool)
    present[index] = True
    frames_out = np.arange(n_frames, dtype=np.int64) + frame_base
    times_out = None
    if time_arr is not None:
        times_out = np.full(n_frames, np.nan)
        times_out[index] = time_arr
    return JointsCSV(path, positions, tuple(names), present, frames_out, times_out)
