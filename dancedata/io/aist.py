"""Read AIST++ annotation files: motion and keypoint pickles, split lists, ignore list.

Pickles go through the restricted unpickler (see :mod:`dancedata.io.safe_pickle`): nothing they
name is executed, and it builds only plain bool/int/float arrays. Every array is checked for
keys, shapes, dtypes and finite values as read, and again as it will be stored: after the
conversion (trans = smpl_trans / smpl_scaling, the float32 cast), where a finite float64 such as
1e300, or a division by a subnormal scaling such as 1e-40, would otherwise become Inf. So a bad
file is refused here with one line naming it, before anything reaches a store.

Plausible ranges of what is stored (a value outside is refused; docs/STORE.md lists them too):

    smpl_scaling          one number in [0.01, 10000]   (AIST++: 89-100)
    motion/axis_angle     |value| <= 100 rad            float32, finite (AIST++: within ±3.5)
    motion/trans          |value| <= 1000 m             float32, finite (AIST++: within ±2.6)
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from dancedata.errors import InputError
from dancedata.io.safe_pickle import load_restricted

# Plausible ranges of stored values (module docstring; docs/STORE.md).
SCALING_RANGE: tuple[float, float] = (0.01, 10_000.0)  # smpl_scaling (smpl_trans units per m)
MAX_ABS_AXIS_ANGLE_RAD = 100.0  # about 16 turns; fitted SMPL poses stay within ±2π
MAX_ABS_TRANS_M = 1_000.0  # root translation; a dance floor is metres wide
MAX_ABS_KEYPOINTS3D_M = 1_000.0  # keypoints3d, keypoints3d_optim after cm -> m
MAX_ABS_PIXELS = 1_000_000.0  # keypoints2d and det_scores: an overflow guard, not plausibility

SPLIT_SCHEMES: tuple[str, ...] = ("crossmodal", "pose")
SPLIT_NAMES: tuple[str, ...] = ("train", "val", "test")


@dataclass(frozen=True)
class AistMotion:
    """One motion pickle, converted: root translation in metres, axis-angle poses (F, 24, 3)."""

    axis_angle: np.ndarray  # (F, 24, 3) float32, radians
    trans_m: np.ndarray  # (F, 3) float32, metres
    scaling: float
    loss: float

    @property
    def n_frames(self) -> int:
        return int(self.axis_angle.shape[0])


def _require_dict(value: object, path: Path) -> dict:
    if not isinstance(value, dict):
        raise InputError(f"expected a dict of arrays, found {type(value).__name__}", path)
    return value


def checked_array(
    data: dict,
    key: str,
    path: Path,
    tail: tuple[int, ...],
    *,
    lead: int | None = None,
    allow_nan: bool = False,
) -> np.ndarray:
    """``data[key]`` as a numeric array of shape (N, *tail) — or (lead, N, *tail) when ``lead``
    is given — with finite values (NaN allowed with ``allow_nan``; Inf never). One InputError
    line naming ``path`` otherwise."""
    if key not in data:
        keys = sorted(str(k)[:40] for k in list(data)[:20])
        raise InputError(f"missing key {key!r} (keys: {keys})", path)
    value = data[key]
    if not isinstance(value, np.ndarray):
        raise InputError(f"{key} is {type(value).__name__}, expected a numpy array", path)
    if value.dtype.kind not in "fiu":
        raise InputError(f"{key} has dtype {value.dtype}, expected numbers", path)
    head = () if lead is None else (lead,)
    n_head = len(head)
    if (
        value.ndim != n_head + 1 + len(tail)
        or value.shape[:n_head] != head
        or value.shape[n_head + 1 :] != tail
    ):
        want = "(" + ", ".join([*map(str, head), "N", *map(str, tail)]) + ")"
        raise InputError(f"{key} has shape {value.shape}, expected {want}", path)
    bad = np.isinf(value) if allow_nan else ~np.isfinite(value)
    if value.dtype.kind == "f" and bad.any():
        frames = np.moveaxis(bad, n_head, 0).reshape(value.shape[n_head], -1)
        first = int(np.argwhere(frames)[0][0])
        what = "Inf" if allow_nan else "NaN or Inf"
        raise InputError(f"{key} holds {what} (first at frame {first})", path)
    return value


def check_stored(
    label: str,
    values: np.ndarray,
    path: Path,
    max_abs: float,
    *,
    units: str = "",
    allow_nan: bool = False,
) -> np.ndarray:
    """``values`` as they will be stored (after conversion and the float32 cast): no Inf (and no
    NaN unless ``allow_nan``), and every value within ±``max_abs``. Frames are axis 0. One
    InputError line naming ``path`` and the first offending frame otherwise."""
    what = f"{label} as stored ({values.dtype}{' ' + units if units else ''})"
    bad = np.isinf(values) if allow_nan else ~np.isfinite(values)
    if bad.any():
        first = int(np.argwhere(bad.reshape(len(values), -1).any(axis=1))[0][0])
        kind = "Inf" if allow_nan or np.isinf(values[first]).any() else "NaN"
        raise InputError(f"{what} holds {kind} (first at frame {first})", path)
    with np.errstate(invalid="ignore"):
        outside = np.abs(values) > max_abs  # NaN compares False
    if outside.any():
        frame, *rest = np.argwhere(outside)[0]
        value = float(values[(frame, *rest)])
        raise InputError(
            f"{what} has {value:.3g} at frame {int(frame)}, outside the plausible range "
            f"±{max_abs:g}",
            path,
        )
    return values


def read_scaling(data: dict, path: Path) -> float:
    """``smpl_scaling``: one number (a size-1 numeric array, or a Python number) within
    :data:`SCALING_RANGE`; a string, list or anything else is one InputError line."""
    if "smpl_scaling" not in data:
        raise InputError("missing key 'smpl_scaling'", path)
    value = data["smpl_scaling"]
    if isinstance(value, np.ndarray):
        if value.dtype.kind not in "fiu" or value.size != 1:
            raise InputError(
                f"smpl_scaling must be one positive number, found {value.dtype} array of "
                f"shape {value.shape}",
                path,
            )
        scaling = float(value.reshape(-1)[0])
    elif isinstance(value, (int, float, np.integer, np.floating)) and not isinstance(
        value, (bool, np.bool_)
    ):
        scaling = float(value)
    else:
        raise InputError(
            f"smpl_scaling is {type(value).__name__}, expected one positive number", path
        )
    if not np.isfinite(scaling) or scaling <= 0:
        raise InputError(f"smpl_scaling must be one positive number, found {scaling:g}", path)
    low, high = SCALING_RANGE
    if not low <= scaling <= high:
        raise InputError(
            f"smpl_scaling {scaling:.3g} is outside the plausible range [{low:g}, {high:g}] "
            "(smpl_trans units per metre; AIST++ has 89-100)",
            path,
        )
    return scaling


def read_motion(path: str | Path) -> AistMotion:
    """Read ``motions/<seq>.pkl``: smpl_poses (N, 72), smpl_trans (N, 3) cm, smpl_scaling (1,).

    Translation in metres is smpl_trans / smpl_scaling, as the AIST++ API computes it. What is
    returned is what gets stored, and it is what is checked: float32, finite, within
    :data:`MAX_ABS_AXIS_ANGLE_RAD` and :data:`MAX_ABS_TRANS_M` (see the module docstring).
    """
    path = Path(path)
    data = _require_dict(load_restricted(path), path)
    poses = checked_array(data, "smpl_poses", path, (72,))
    trans = checked_array(data, "smpl_trans", path, (3,))
    scaling = read_scaling(data, path)
    if poses.shape[0] == 0:
        raise InputError("motion has zero frames", path)
    if poses.shape[0] != trans.shape[0]:
        raise InputError(
            f"smpl_poses has {poses.shape[0]} frames but smpl_trans has {trans.shape[0]}", path
        )
    loss = data.get("smpl_loss", float("nan"))
    try:
        loss = float(np.asarray(loss).reshape(-1)[0])
    except OverflowError:
        loss = float("inf")
    except (TypeError, ValueError, IndexError):
        loss = float("nan")  # not a number: stored as missing, as before
    if np.isinf(loss):
        raise InputError("smpl_loss is infinite (as stored, float64)", path)
    with np.errstate(over="ignore"):  # overflow to Inf is found by check_stored below
        axis_angle = poses.reshape(-1, 24, 3).astype(np.float32)
        trans_m = (trans.astype(np.float64) / scaling).astype(np.float32)
    check_stored("smpl_poses", axis_angle, path, MAX_ABS_AXIS_ANGLE_RAD, units="rad")
    check_stored("smpl_trans / smpl_scaling", trans_m, path, MAX_ABS_TRANS_M, units="m")
    return AistMotion(axis_angle=axis_angle, trans_m=trans_m, scaling=scaling, loss=loss)


def read_name_list(path: str | Path) -> list[str]:
    """Sequence names, one per line; every line stripped (the real ignore list has a trailing
    space on one line) and blank lines dropped. Order kept, duplicates removed."""
    path = Path(path)
    try:
        text = path.read_text(encoding="utf-8")
    except UnicodeDecodeError:
        raise InputError("split file is not UTF-8 text", path) from None
    except OSError as exc:
        raise InputError(f"cannot read: {exc.strerror}", path) from None
    names = [line.strip() for line in text.splitlines()]
    return list(dict.fromkeys(name for name in names if name))


def find_split_files(raw: Path) -> dict[tuple[str, str], Path]:
    """``{(scheme, split): path}`` for every ``splits/<scheme>_<split>.txt`` present."""
    found: dict[tuple[str, str], Path] = {}
    for scheme in SPLIT_SCHEMES:
        for split in SPLIT_NAMES:
            for folder in (raw / "splits", raw):
                candidate = folder / f"{scheme}_{split}.txt"
                if candidate.is_file():
                    found[(scheme, split)] = candidate
                    break
    return found


def find_ignore_list(raw: Path) -> Path | None:
    """``ignore_list.txt`` at the annotation root (or in splits/, where some mirrors keep it)."""
    for candidate in (raw / "ignore_list.txt", raw / "splits" / "ignore_list.txt"):
        if candidate.is_file():
            return candidate
    return None
