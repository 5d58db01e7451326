"""Read AIST++ annotation files: motion and keypoint pickles, split lists, ignore list.

Pickles go through the restricted unpickler (see :mod:`dancedata.safe_pickle`): nothing they
name is executed. Every array is checked for keys, shapes, dtypes and finite values, so a bad file
is refused here with one line naming it, before anything reaches a store.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from dancedata.errors import InputError
from dancedata.safe_pickle import load_restricted

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
        raise InputError(f"missing key {key!r} (keys: {sorted(map(str, data))})", path)
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


def read_motion(path: str | Path) -> AistMotion:
    """Read ``motions/<seq>.pkl``: smpl_poses (N, 72), smpl_trans (N, 3) cm, smpl_scaling (1,).

    Translation in metres is smpl_trans / smpl_scaling, as the AIST++ API computes it.
    """
    path = Path(path)
    data = _require_dict(load_restricted(path), path)
    poses = checked_array(data, "smpl_poses", path, (72,))
    trans = checked_array(data, "smpl_trans", path, (3,))
    if "smpl_scaling" not in data:
        raise InputError("missing key 'smpl_scaling'", path)
    scaling = np.asarray(data["smpl_scaling"], dtype=np.float64).reshape(-1)
    if scaling.size != 1 or not np.isfinite(scaling[0]) or scaling[0] <= 0:
        raise InputError(f"smpl_scaling must be one positive number, found {scaling}", path)
    if poses.shape[0] == 0:
        raise InputError("motion has zero frames", path)
    if poses.shape[0] != trans.shape[0]:
        raise InputError(
            f"smpl_poses has {poses.shape[0]} frames but smpl_trans has {trans.shape[0]}", path
        )
    loss = data.get("smpl_loss", float("nan"))
    try:
        loss = float(np.asarray(loss).reshape(-1)[0])
    except (TypeError, ValueError, IndexError):
        loss = float("nan")
    return AistMotion(
        axis_angle=poses.reshape(-1, 24, 3).astype(np.float32),
        trans_m=(trans.astype(np.float64) / scaling[0]).astype(np.float32),
        scaling=float(scaling[0]),
        loss=loss,
    )


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
