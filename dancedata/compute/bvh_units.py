"""Length units of BVH files, and the sanity check that catches a wrong one.

BVH has no unit field. Files in the wild use centimetres (Mixamo, Perception Neuron, most
exporters), inches, metres or odd scales (the CMU "cgspeed" conversion uses 1/0.45 inch:
0.056444 m per unit). ``--units`` names the unit, or gives metres per file unit as a number.

The check: a rig's size is the largest side of the body's bounding box *within a frame*,
maximised over frames (about the body height for a standing or T-posed human, the arm span when
that is larger). Measured per frame, so a dancer travelling across the floor does not count the
distance travelled; and joints that never move while others do (a static reference root at the
origin, as some exporters write above the hips) are left out, so a body far from the origin is
not measured together with the origin. A size outside 0.3-3 m after conversion almost always
means a wrong ``--units``: the error suggests, of the usual conventions (:data:`CONVENTIONS`:
CMU's 0.056444, inches, cm, m, mm), the one giving the size nearest 1.7 m. A size inside those
bounds but outside 1-2.5 m is stored with a warning naming the same suggestion.
"""

from __future__ import annotations

import math
import warnings
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from dancedata.errors import InputError

__all__ = [
    "CONVENTIONS",
    "PLAUSIBLE_SIZE_M",
    "UNITS",
    "USUAL_SIZE_M",
    "LengthUnit",
    "best_convention",
    "check_rig_size",
    "parse_units",
    "passing_units",
    "rig_size",
    "size_warning",
    "static_joints",
]

UNITS: dict[str, float] = {"m": 1.0, "dm": 0.1, "cm": 0.01, "mm": 0.001, "in": 0.0254, "ft": 0.3048}
PLAUSIBLE_SIZE_M = (0.3, 3.0)
# Inside the hard bounds but unusual for a person (a rig size is about the height, or the arm
# span when larger): ingest warns, naming the convention that gives a more usual size.
USUAL_SIZE_M = (1.0, 2.5)
_TYPICAL_SIZE_M = 1.7
# The conventions BVH files in the wild use, as ``--units`` values, with what they are. Only
# these are suggested (dm or ft fit many sizes and no exporter uses them).
CONVENTIONS: tuple[tuple[str, str], ...] = (
    ("0.056444", "CMU cgspeed BVH, 1/0.45 in"),
    ("in", "inches"),
    ("cm", "centimetres"),
    ("m", "metres"),
    ("mm", "millimetres"),
)


@dataclass(frozen=True)
class LengthUnit:
    """A file length unit: ``name`` as given and ``metres`` per unit."""

    name: str
    metres: float


def parse_units(text: str) -> LengthUnit:
    """``"cm"`` (any of :data:`UNITS`) or a positive number of metres per unit."""
    key = text.strip().lower()
    if key in UNITS:
        return LengthUnit(key, UNITS[key])
    try:
        value = float(key)
    except ValueError:
        value = math.nan
    if not (math.isfinite(value) and value > 0):
        raise InputError(
            f"--units {text!r}: give one of {', '.join(UNITS)} or metres per file unit "
            "(e.g. 0.056444 for CMU cgspeed BVH)"
        )
    return LengthUnit(repr(value), value)


def static_joints(positions: np.ndarray, rtol: float = 1e-9) -> np.ndarray:
    """(J,) bool: joints whose world position never moves over the frames while some other joint
    does (a static reference root); all False for one frame or a motionless clip."""
    p = np.asarray(positions, dtype=np.float64)
    if p.ndim != 3 or p.shape[0] < 2 or not np.isfinite(p).any():
        return np.zeros(p.shape[1] if p.ndim == 3 else 0, dtype=bool)
    with np.errstate(invalid="ignore"), warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)
        travel = np.nanmax(np.nanmax(p, axis=0) - np.nanmin(p, axis=0), axis=1)  # (J,)
        scale = float(np.nanmax(np.abs(p)))
    moves = travel > rtol * max(scale, 1e-300)
    if not moves.any():
        return np.zeros(p.shape[1], dtype=bool)
    return ~moves & np.isfinite(travel)


def rig_size(positions: np.ndarray) -> float:
    """Body size in the positions' units: the largest side of the bounding box of the joints
    within one frame, maximised over frames, leaving out :func:`static_joints`. Frames or
    joints holding NaN are ignored; 0.0 when nothing is finite."""
    p = np.asarray(positions, dtype=np.float64)
    if p.size == 0:
        return 0.0
    if p.ndim == 3:
        p = p[:, ~static_joints(p)]
    with np.errstate(invalid="ignore"), warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)
        side = np.nanmax(p, axis=1) - np.nanmin(p, axis=1) if np.isfinite(p).any() else None
    if side is None or not np.isfinite(side).any():
        return 0.0
    return float(np.nanmax(side))


def passing_units(size_in_file_units: float) -> list[str]:
    """Named units under which the size lies in :data:`PLAUSIBLE_SIZE_M`, nearest a typical
    human height (1.7 m, on a log scale) first."""
    low, high = PLAUSIBLE_SIZE_M
    if not size_in_file_units > 0:
        return []
    fits = [u for u in UNITS if low <= size_in_file_units * UNITS[u] <= high]
    return sorted(
        fits, key=lambda u: abs(math.log(size_in_file_units * UNITS[u] / _TYPICAL_SIZE_M))
    )


def _metres(units: str) -> float:
    return UNITS[units] if units in UNITS else float(units)


def best_convention(
    size_in_file_units: float, exclude: float | None = None
) -> tuple[str, str, float] | None:
    """The :data:`CONVENTIONS` entry giving the size nearest a typical 1.7 m (log scale) among
    those inside :data:`PLAUSIBLE_SIZE_M`, as (units, what it is, size in m); ``exclude``
    (metres per unit) leaves the current unit out. None when none fits."""
    low, high = PLAUSIBLE_SIZE_M
    if not size_in_file_units > 0:
        return None
    best = None
    for units, what in CONVENTIONS:
        metres = _metres(units)
        if exclude is not None and math.isclose(metres, exclude, rel_tol=1e-9):
            continue
        size = size_in_file_units * metres
        if low <= size <= high:
            score = abs(math.log(size / _TYPICAL_SIZE_M))
            if best is None or score < best[0]:
                best = (score, units, what, size)
    return None if best is None else best[1:]


def _suggest(units: str, what: str, size_m: float) -> str:
    return f"--units {units} ({what}) makes it {size_m:.3g} m"


def size_warning(size_m: float, unit: LengthUnit) -> str | None:
    """A warning when ``size_m`` passes :data:`PLAUSIBLE_SIZE_M` but is outside
    :data:`USUAL_SIZE_M`, with the convention that gives a more usual size (None: usual)."""
    low, high = USUAL_SIZE_M
    if not size_m > 0 or low <= size_m <= high:
        return None
    kind = "small" if size_m < low else "large"
    text = (
        f"the body measures {size_m:.3g} m with --units {unit.name}, {kind} for a person "
        f"(usually {low:g}-{high:g} m)"
    )
    best = best_convention(size_m / unit.metres, exclude=unit.metres)
    if best is not None and abs(math.log(best[2] / _TYPICAL_SIZE_M)) < abs(
        math.log(size_m / _TYPICAL_SIZE_M)
    ):
        text += f": if that is wrong, {_suggest(*best)}"
    return text


def check_rig_size(size_m: float, unit: LengthUnit, path: str | Path) -> None:
    """Raise InputError naming ``path`` when ``size_m`` is outside :data:`PLAUSIBLE_SIZE_M`."""
    low, high = PLAUSIBLE_SIZE_M
    if low <= size_m <= high:
        return
    in_file = size_m / unit.metres
    best = best_convention(in_file, exclude=unit.metres)
    if best is not None:
        hint = (
            f"of the usual conventions, {_suggest(*best)}; or pass metres per file unit as a number"
        )
    elif in_file > 0:
        hint = (
            f"no usual convention fits; pass metres per unit as a number (--units "
            f"{_TYPICAL_SIZE_M / in_file:.3g} makes it {_TYPICAL_SIZE_M:g} m)"
        )
    else:
        hint = "the joints do not span any length (every joint at one point)"
    raise InputError(
        f"the body measures {in_file:.4g} file units = {size_m:.3g} m with --units {unit.name}, "
        f"outside a plausible {low:g}-{high:g} m: {hint}; --no-size-check skips this check",
        path,
    )
