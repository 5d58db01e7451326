"""Length units of BVH files, and the sanity check that catches a wrong one.

BVH has no unit field. Files in the wild use centimetres (Mixamo, Perception Neuron, most
exporters), inches, metres or odd scales (the CMU "cgspeed" conversion uses 1/0.45 inch:
0.056444 m per unit). ``--units`` names the unit, or gives metres per file unit as a number.

The check: a rig's size is the largest side of the joints' bounding box, maximised over frames
(about the body height for a standing or T-posed human, the arm span when that is larger). A
size outside 0.3-3 m after conversion almost always means a wrong ``--units``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from dancedata.errors import InputError

__all__ = ["PLAUSIBLE_SIZE_M", "UNITS", "LengthUnit", "check_rig_size", "parse_units", "rig_size"]

UNITS: dict[str, float] = {"m": 1.0, "dm": 0.1, "cm": 0.01, "mm": 0.001, "in": 0.0254, "ft": 0.3048}
PLAUSIBLE_SIZE_M = (0.3, 3.0)
_TYPICAL_SIZE_M = 1.7


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


def rig_size(positions: np.ndarray) -> float:
    """Largest side of the joints' bounding box over all frames, in the positions' units.
    Frames or joints holding NaN are ignored; 0.0 when nothing is finite."""
    p = np.asarray(positions, dtype=np.float64)
    if p.size == 0:
        return 0.0
    with np.errstate(invalid="ignore"):
        side = np.nanmax(p, axis=1) - np.nanmin(p, axis=1) if np.isfinite(p).any() else None
    if side is None or not np.isfinite(side).any():
        return 0.0
    return float(np.nanmax(side))


def _suggestion(size_in_file_units: float) -> str:
    """The common unit giving a size nearest a typical human height (on a log scale)."""
    if not size_in_file_units > 0:
        return "m"
    return min(
        ("m", "cm", "mm", "in", "ft"),
        key=lambda u: abs(math.log(size_in_file_units * UNITS[u] / _TYPICAL_SIZE_M)),
    )


def check_rig_size(size_m: float, unit: LengthUnit, path: str | Path) -> None:
    """Raise InputError naming ``path`` when ``size_m`` is outside :data:`PLAUSIBLE_SIZE_M`."""
    low, high = PLAUSIBLE_SIZE_M
    if low <= size_m <= high:
        return
    in_file = size_m / unit.metres
    guess = _suggestion(in_file)
    raise InputError(
        f"the rig measures {in_file:.4g} file units = {size_m:.3g} m with --units {unit.name}, "
        f"outside a plausible {low:g}-{high:g} m: pass the file's unit, e.g. --units {guess} "
        f"({in_file * UNITS[guess]:.3g} m), or metres per unit as a number (CMU cgspeed: "
        "0.056444); --no-size-check skips this check",
        path,
    )
