"""Assemble a view's frames from its parts: the arrays side by side, FACT's zero columns filled.

A view (:mod:`dancedata.read.views`) is an ordered list of parts; each part is a (rows, width)
float32 array, or None for the six zero columns FACT puts before the root translation. Pure
numpy: the store reader hands the arrays in.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

ZERO_COLUMNS = 6  # FACT's 225-d motion starts with six zeros (its unused "smpl_trans" slot)


def stack_parts(parts: Sequence[np.ndarray | None], start: int, stop: int) -> np.ndarray:
    """(stop − start, Σ widths) float32: rows [start, stop) of every part, side by side, with
    :data:`ZERO_COLUMNS` zero columns where a part is None. Parts must be 2-d float32 with at
    least ``stop`` rows (a shorter part would silently give fewer rows, so it is refused)."""
    n = stop - start
    columns = []
    for part in parts:
        if part is None:
            columns.append(np.zeros((n, ZERO_COLUMNS), np.float32))
            continue
        if part.ndim != 2 or part.shape[0] < stop:
            raise ValueError(f"view part of shape {part.shape} cannot give rows [{start}, {stop})")
        columns.append(part[start:stop])
    return np.concatenate(columns, axis=1)


def common_length(parts: Sequence[np.ndarray | None]) -> int:
    """The rows every non-None part has (the shortest part's length); ValueError when every
    part is None (a view of zero columns only has no frame count)."""
    lengths = [p.shape[0] for p in parts if p is not None]
    if not lengths:
        raise ValueError("a view needs at least one part with frames")
    return min(lengths)


def part_widths(parts: Sequence[np.ndarray | None]) -> list[int]:
    """Columns of each part: :data:`ZERO_COLUMNS` for None, else the part's width."""
    return [ZERO_COLUMNS if p is None else int(p.shape[1]) for p in parts]
