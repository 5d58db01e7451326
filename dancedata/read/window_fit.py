"""Bring a variable-length window to a fixed number of frames: resample, crop or pad.

``fit`` (the ``fit=`` option of the datasets in :mod:`dancedata.read.torch_data`):

* ``"resample"`` — every window becomes ``window_frames`` frames spanning the same time: output
  frame ``j`` sits at source frame ``j · (L − 1) / (W − 1)`` (first and last frames kept,
  "align corners"), so a one-measure window gets a fixed number of frames per measure whatever
  the tempo. Each part of the view is resampled by the method its data needs
  (:data:`PART_RESAMPLERS`, recorded as ``dataset.resampling``):

  - ``slerp``: ``motion/rotmat`` — per joint, matrices → unit quaternions, spherical linear
    interpolation along the shorter arc between the two neighbouring frames, → matrices;
    ``slerp_quat`` (``motion/quat``, wxyz), ``slerp_rot6d`` / ``slerp_rot6d_rows``
    (``motion/rot6d``, ``motion/rot6d_rows``: decoded by Gram–Schmidt, re-encoded) and
    ``slerp_axis_angle`` (``motion/axis_angle``) the same on the other stored rotations;
  - ``nearest``: integer arrays that are not events (masks and codes such as
    ``motion/positions_mask``) — the value of the nearest source frame, never a blend;
  - ``linear``: ``motion/trans`` (metres), audio features (``onset_env``, ``mfcc``,
    ``chroma_cens``, per-stem ones) and ``motion/euler``. Euler angles are interpolated per
    angle on the stored values (which featurize keeps continuous in time), not on the rotation
    group: between neighbouring frames at 60 fps this is within a small fraction of a degree of
    SLERP, but not equal to it, and wrong across a 2π jump;
  - ``event``: 0/1 event columns (``onset_peaks``, ``beats``, ``beats_bailando``, the motion
    beats ``motion_beats_mint`` / ``motion_beats_bailando``) — each event moves to the
    nearest output frame ``round(i · (W − 1) / (L − 1))`` (the count is kept unless two events
    land on one frame), instead of being smeared by interpolation;
  - ``zeros``: FACT's six zero columns stay zero.

* ``"crop"`` — the first ``window_frames`` frames (a measure window starts on its downbeat);
  shorter windows are zero-padded at the end and their ``mask`` marks the real frames.
* ``"pad"`` — windows are zero-padded at the end to ``window_frames``; no frame is ever
  dropped, so a window longer than ``window_frames`` is an error (raised when the dataset is
  made, naming the longest window).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from dancedata.compute.resample import resample_linear, resample_quaternions
from dancedata.compute.rotations import (
    axis_angle_to_quat,
    quat_to_axis_angle,
    quat_to_rotmat,
    rot6d_rows_to_rotmat,
    rot6d_to_rotmat,
    rotmat_to_rot6d,
    rotmat_to_rot6d_rows,
)
from dancedata.errors import InputError

FIT_MODES = ("resample", "crop", "pad")
EVENT_ARRAYS = (
    "onset_peaks",
    "beats",
    "beats_bailando",
    "motion_beats_mint",
    "motion_beats_bailando",
)
ROTATION_RESAMPLERS = {
    "rotmat": "slerp",
    "quat": "slerp_quat",
    "rot6d": "slerp_rot6d",
    "rot6d_rows": "slerp_rot6d_rows",
    "axis_angle": "slerp_axis_angle",
}
PART_RESAMPLERS = {
    "zeros6": "zeros",
    "motion/rotmat": "slerp",
    "motion/quat": "slerp_quat",
    "motion/rot6d": "slerp_rot6d",
    "motion/rot6d_rows": "slerp_rot6d_rows",
    "motion/axis_angle": "slerp_axis_angle",
    "motion/trans": "linear",
    "motion/euler": "linear",
    "*onset_peaks, *beats, *beats_bailando, motion/motion_beats_*": "event",
    "other integer arrays (masks, codes)": "nearest",
    "every other array": "linear",
}


@dataclass(frozen=True)
class ColumnPart:
    """Columns ``[start, stop)`` of a view hold ``name``, resampled by ``method``."""

    name: str
    start: int
    stop: int
    method: str
    shape: tuple[int, ...] = ()  # the array's row shape (columns are it flattened, C order)


def part_method(kind: str, array: str, dtype: np.dtype | None = None) -> str:
    """The resampler of one view part (see :data:`PART_RESAMPLERS`); ``dtype`` (the stored
    one) sends integer arrays that are not events to ``nearest``."""
    if kind == "zeros6":
        return "zeros"
    if array.rsplit("/", 1)[-1] in EVENT_ARRAYS:
        return "event"
    if kind == "motion" and array in ROTATION_RESAMPLERS:
        return ROTATION_RESAMPLERS[array]
    if dtype is not None and np.issubdtype(dtype, np.integer):
        return "nearest"
    return "linear"


def column_plan(
    parts: list[tuple[str, str]],
    widths: list[int],
    shapes: list[tuple[int, ...]] | None = None,
    dtypes: list[np.dtype | None] | None = None,
) -> list[ColumnPart]:
    """The column plan of a view given its parts (``read.views.layouts.spec_parts``), their widths
    and (optionally) the arrays' row shapes and stored dtypes."""
    plan: list[ColumnPart] = []
    at = 0
    for k, ((kind, array), width) in enumerate(zip(parts, widths, strict=True)):
        name = "zeros6" if kind == "zeros6" else f"{kind}/{array}"
        shape = shapes[k] if shapes is not None else (width,)
        dtype = dtypes[k] if dtypes is not None else None
        plan.append(ColumnPart(name, at, at + width, part_method(kind, array, dtype), shape))
        at += width
    return plan


def resample_positions(length: int, window_frames: int) -> np.ndarray:
    """(W,) float64 source-frame positions of the W output frames (first and last kept)."""
    if window_frames == 1 or length == 1:
        return np.zeros(window_frames)
    return np.arange(window_frames) * ((length - 1) / (window_frames - 1))


def orthonormal_rotmat_to_quat(rotmat: np.ndarray) -> np.ndarray:
    """(..., 3, 3) rotation matrices → (..., 4) wxyz unit quaternions by Shepperd's method
    (the largest of w², x², y², z² picks the stable formula). Assumes orthonormal input, as
    stored rotmat is; scipy's ``from_matrix`` orthonormalises by SVD first, ~20× slower."""
    m = np.asarray(rotmat, dtype=np.float64)
    m00, m11, m22 = m[..., 0, 0], m[..., 1, 1], m[..., 2, 2]
    trace = m00 + m11 + m22
    squares = np.stack([trace, 2 * m00 - trace, 2 * m11 - trace, 2 * m22 - trace], -1)
    pick = np.argmax(squares, axis=-1)
    big = np.sqrt(np.maximum(1.0 + np.take_along_axis(squares, pick[..., None], -1)[..., 0], 0))
    d21, d02, d10 = (
        m[..., 2, 1] - m[..., 1, 2],
        m[..., 0, 2] - m[..., 2, 0],
        m[..., 1, 0] - m[..., 0, 1],
    )
    s01, s02, s12 = (
        m[..., 0, 1] + m[..., 1, 0],
        m[..., 0, 2] + m[..., 2, 0],
        m[..., 1, 2] + m[..., 2, 1],
    )
    candidates = (
        np.stack([big, d21 / big, d02 / big, d10 / big], -1),
        np.stack([d21 / big, big, s01 / big, s02 / big], -1),
        np.stack([d02 / big, s01 / big, big, s12 / big], -1),
        np.stack([d10 / big, s02 / big, s12 / big, big], -1),
    )
    # big ≥ 1 (the four squares, each 4q_i² − 1, sum to 0), so no division is unsafe.
    q = np.select([(pick == k)[..., None] for k in range(4)], candidates)
    q *= 0.5
    return q / np.linalg.norm(q, axis=-1, keepdims=True)


def _slerp_rotmat(values: np.ndarray, positions: np.ndarray) -> np.ndarray:
    n, width = values.shape
    if width % 9:
        raise InputError(f"rotation-matrix columns must come in 9s (got {width})")
    quat = orthonormal_rotmat_to_quat(values.reshape(n, width // 9, 3, 3))
    return quat_to_rotmat(resample_quaternions(quat, positions)).reshape(len(positions), width)


_ENCODINGS = {
    "slerp_quat": (lambda q: q, lambda q: q, 4),
    "slerp_rot6d": (
        lambda r: orthonormal_rotmat_to_quat(rot6d_to_rotmat(r)),
        lambda q: rotmat_to_rot6d(quat_to_rotmat(q)),
        6,
    ),
    "slerp_rot6d_rows": (
        lambda r: orthonormal_rotmat_to_quat(rot6d_rows_to_rotmat(r)),
        lambda q: rotmat_to_rot6d_rows(quat_to_rotmat(q)),
        6,
    ),
    "slerp_axis_angle": (axis_angle_to_quat, quat_to_axis_angle, 3),
}


def _slerp_encoded(values: np.ndarray, positions: np.ndarray, method: str) -> np.ndarray:
    """SLERP of rotations stored as quaternions, 6D or axis-angle: decoded to quaternions,
    interpolated, encoded back (columns come in groups of the encoding's width)."""
    to_quat, from_quat, size = _ENCODINGS[method]
    n, width = values.shape
    if width % size:
        raise InputError(f"{method} columns must come in {size}s (got {width})")
    quat = to_quat(values.reshape(n, width // size, size).astype(np.float64))
    return from_quat(resample_quaternions(quat, positions)).reshape(len(positions), width)


def _nearest(values: np.ndarray, positions: np.ndarray) -> np.ndarray:
    index = np.minimum(np.floor(positions + 0.5).astype(np.int64), values.shape[0] - 1)
    return values[index]


def _events(values: np.ndarray, window_frames: int) -> np.ndarray:
    n = values.shape[0]
    out = np.zeros((window_frames, values.shape[1]), dtype=np.float64)
    if n == 1:
        target = np.zeros(1, dtype=np.int64)
    else:
        target = np.floor(np.arange(n) * ((window_frames - 1) / (n - 1)) + 0.5).astype(np.int64)
    for c in range(values.shape[1]):
        hit = values[:, c] != 0
        np.maximum.at(out[:, c], target[hit], values[hit, c])
    return out


def resample_window(x: np.ndarray, plan: list[ColumnPart], window_frames: int) -> np.ndarray:
    """(L, D) view rows → (W, D) float32, each part by its method."""
    positions = resample_positions(x.shape[0], window_frames)
    out = np.zeros((window_frames, x.shape[1]), dtype=np.float32)
    for part in plan:
        values = x[:, part.start : part.stop]
        if part.method == "zeros":
            continue
        if part.method == "slerp":
            out[:, part.start : part.stop] = _slerp_rotmat(values, positions)
        elif part.method in _ENCODINGS:
            out[:, part.start : part.stop] = _slerp_encoded(values, positions, part.method)
        elif part.method == "nearest":
            out[:, part.start : part.stop] = _nearest(values, positions)
        elif part.method == "event":
            out[:, part.start : part.stop] = _events(values, window_frames)
        else:
            out[:, part.start : part.stop] = resample_linear(values, positions)
    return out


def fit_window(
    x: np.ndarray, plan: list[ColumnPart], window_frames: int, fit: str
) -> tuple[np.ndarray, int]:
    """(L, D) → ((W, D) float32, number of real frames at the start of it)."""
    if fit not in FIT_MODES:
        raise InputError(f"fit must be one of {', '.join(FIT_MODES)} (got {fit!r})")
    length = x.shape[0]
    if fit == "resample":
        return resample_window(x, plan, window_frames), window_frames
    if length > window_frames and fit == "pad":
        raise InputError(
            f"fit='pad' never drops frames, but this window has {length} > window_frames="
            f"{window_frames} (use fit='crop' or 'resample')"
        )
    kept = min(length, window_frames)
    out = np.zeros((window_frames, x.shape[1]), dtype=np.float32)
    out[:kept] = x[:kept]
    return out, kept
