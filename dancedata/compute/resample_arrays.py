"""One sequence's stored arrays at another frame rate: which rule each array takes, and the rules.

Frame times: output frame ``i`` sits at ``i / dst_fps`` seconds, i.e. at source frame position
``i · src_fps / dst_fps``; only times inside the source clip are produced, so

    n_out = floor((n_in − 1) · dst_fps / src_fps) + 1          (0 for an empty clip)

(:func:`dancedata.compute.resample.resampled_frame_count`; when ``src_fps / dst_fps`` is an
integer k the output is every k-th frame, bit for bit, and ``n_out = (n_in − 1) // k + 1``).

Rules (named as the manifest records them):

* ``slerp``: rotations (axis-angle, rotation matrices, Euler angles, quaternions, both 6D
  layouts) are converted to unit quaternions (wxyz), interpolated by SLERP between the two
  neighbouring source frames along the shorter arc, and converted back; quaternions are made
  sign-continuous in time again.
* ``linear``: positions, translations, keypoints, scores and every other float array,
  component-wise linear interpolation between the two neighbouring source frames (a NaN
  neighbour gives NaN: gaps are not bridged).
* ``nearest_event``: per-frame event flags (motion beats): an event at source frame ``j`` is put
  on output frame ``floor(j · dst_fps / src_fps + 0.5)`` (nearest, ties up), clipped to the clip.
* ``nearest``: integer codes (masks): the value of the nearest source frame
  ``floor(position + 0.5)``.
* ``recompute``: arrays computed over windows of frames whose length is set in frames (Laban
  efforts, the Weight effort): not resampled; the featurize family recomputes them at the new
  rate.
"""

from __future__ import annotations

import numpy as np

from dancedata.compute.resample import (
    decimation_step,
    resample_linear,
    resample_positions,
    resample_quaternions,
    resampled_frame_count,
)
from dancedata.compute.rotations import (
    axis_angle_to_quat,
    euler_to_rotmat,
    quat_sign_continuous,
    quat_to_axis_angle,
    quat_to_rotmat,
    rot6d_rows_to_rotmat,
    rot6d_to_rotmat,
    rotmat_to_euler,
    rotmat_to_quat,
    rotmat_to_rot6d,
    rotmat_to_rot6d_rows,
)

__all__ = [
    "ROTATION_ARRAYS",
    "RULES",
    "resample_array",
    "resample_events",
    "resample_nearest",
    "resample_rotations",
    "rule_of",
]

RULES = ("slerp", "linear", "nearest_event", "nearest", "recompute")
# motion array name → the rotation format it holds
ROTATION_ARRAYS = {
    "axis_angle": "axis_angle",
    "rotmat": "rotmat",
    "euler": "euler",
    "quat": "quat",
    "rot6d": "rot6d",
    "rot6d_rows": "rot6d_rows",
}
_EVENT_ARRAYS = ("motion_beats_mint", "motion_beats_bailando")
_RECOMPUTE_PREFIXES = ("laban_", "weight_effort")


def rule_of(name: str, dtype: np.dtype) -> str:
    """The rule for motion array ``name`` (its path under ``motion/``) of ``dtype``."""
    if name in ROTATION_ARRAYS:
        return "slerp"
    if name in _EVENT_ARRAYS:
        return "nearest_event"
    if name.startswith(_RECOMPUTE_PREFIXES):
        return "recompute"
    if np.dtype(dtype).kind == "f":
        return "linear"
    return "nearest"


def _to_quat(values: np.ndarray, fmt: str, order: str | list[str] | None) -> np.ndarray:
    if fmt == "axis_angle":
        return axis_angle_to_quat(values)
    if fmt == "quat":
        return values / np.linalg.norm(values, axis=-1, keepdims=True)
    if fmt == "rotmat":
        return rotmat_to_quat(values)
    if fmt == "rot6d":
        return rotmat_to_quat(rot6d_to_rotmat(values))
    if fmt == "rot6d_rows":
        return rotmat_to_quat(rot6d_rows_to_rotmat(values))
    if fmt == "euler":
        return rotmat_to_quat(_euler_rotmat(values, order))
    raise ValueError(f"unknown rotation format {fmt!r}")


def _euler_rotmat(values: np.ndarray, order: str | list[str] | None) -> np.ndarray:
    if order is None:
        raise ValueError("Euler angles need their order")
    if isinstance(order, str):
        return euler_to_rotmat(values, order)
    out = np.empty(values.shape[:-1] + (3, 3))
    for o in set(order):
        joints = [j for j, x in enumerate(order) if x == o]
        out[:, joints] = euler_to_rotmat(values[:, joints], o)
    return out


def _from_quat(quat: np.ndarray, fmt: str, order: str | list[str] | None) -> np.ndarray:
    if fmt == "axis_angle":
        return quat_to_axis_angle(quat)
    if fmt == "quat":
        return quat_sign_continuous(quat)
    rotmat = quat_to_rotmat(quat)
    if fmt == "rotmat":
        return rotmat
    if fmt == "rot6d":
        return rotmat_to_rot6d(rotmat)
    if fmt == "rot6d_rows":
        return rotmat_to_rot6d_rows(rotmat)
    if order is None:
        raise ValueError("Euler angles need their order")
    if isinstance(order, str):
        return rotmat_to_euler(rotmat, order)
    out = np.empty(quat.shape[:-1] + (3,))
    for o in set(order):
        joints = [j for j, x in enumerate(order) if x == o]
        out[:, joints] = rotmat_to_euler(rotmat[:, joints], o)
    return out


def resample_rotations(
    values: np.ndarray,
    fmt: str,
    src_fps: float,
    dst_fps: float,
    order: str | list[str] | None = None,
) -> np.ndarray:
    """(F, J, ...) rotations in ``fmt`` at ``src_fps`` → (n_out, J, ...) at ``dst_fps`` by
    SLERP of their quaternions (every k-th frame copied exactly for an integer rate ratio)."""
    values = np.asarray(values)
    n_out = resampled_frame_count(values.shape[0], src_fps, dst_fps)
    k = decimation_step(src_fps, dst_fps)
    if k is not None:
        return values[::k][:n_out].copy()
    quat = quat_sign_continuous(_to_quat(values.astype(np.float64), fmt, order))
    positions = resample_positions(values.shape[0], src_fps, dst_fps)
    out = _from_quat(resample_quaternions(quat, positions), fmt, order)
    # output frames on a source frame keep its stored values (not a re-encoding of them:
    # an axis-angle of more than π or a quaternion's sign would change)
    on_frame = np.abs(positions - np.round(positions)) < 1e-9
    out[on_frame] = values[np.round(positions[on_frame]).astype(np.int64)]
    return out


def resample_values(values: np.ndarray, src_fps: float, dst_fps: float) -> np.ndarray:
    """(F, ...) values, linear in time (exact copies of every k-th frame for an integer ratio)."""
    values = np.asarray(values)
    k = decimation_step(src_fps, dst_fps)
    if k is not None:
        return values[::k].copy()
    return resample_linear(values, resample_positions(values.shape[0], src_fps, dst_fps))


def resample_events(flags: np.ndarray, src_fps: float, dst_fps: float) -> np.ndarray:
    """(F,) event flags → (n_out,) with each event on its nearest output frame (ties up)."""
    flags = np.asarray(flags)
    n_out = resampled_frame_count(flags.shape[0], src_fps, dst_fps)
    out = np.zeros((n_out,) + flags.shape[1:], dtype=flags.dtype)
    if n_out == 0:
        return out
    events = np.flatnonzero(flags.reshape(flags.shape[0], -1).any(axis=1))
    target = np.clip(np.floor(events * (dst_fps / src_fps) + 0.5).astype(np.int64), 0, n_out - 1)
    out[target] = flags[events]
    return out


def resample_nearest(values: np.ndarray, src_fps: float, dst_fps: float) -> np.ndarray:
    """(F, ...) codes → (n_out, ...): each output frame takes its nearest source frame."""
    values = np.asarray(values)
    positions = resample_positions(values.shape[0], src_fps, dst_fps)
    idx = np.clip(np.floor(positions + 0.5).astype(np.int64), 0, max(values.shape[0] - 1, 0))
    return values[idx].copy()


def resample_array(
    values: np.ndarray,
    rule: str,
    src_fps: float,
    dst_fps: float,
    rotation_format: str | None = None,
    euler_order: str | list[str] | None = None,
) -> np.ndarray:
    """One sequence's (F, ...) array by ``rule`` (see the module docstring), in its dtype."""
    dtype = np.asarray(values).dtype
    if rule == "slerp":
        if rotation_format is None:
            raise ValueError("slerp needs the rotation format")
        out = resample_rotations(values, rotation_format, src_fps, dst_fps, euler_order)
    elif rule == "linear":
        out = resample_values(values, src_fps, dst_fps)
    elif rule == "nearest_event":
        out = resample_events(values, src_fps, dst_fps)
    elif rule == "nearest":
        out = resample_nearest(values, src_fps, dst_fps)
    else:
        raise ValueError(f"rule {rule!r} does not resample (choose from {RULES[:4]})")
    return np.asarray(out).astype(dtype, copy=False)
