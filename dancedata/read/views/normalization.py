"""The normalisation statistics a version stores (``dancedata stats``), shaped like an array row.

``normalization(reader, "motion/quat")`` returns the mean and standard deviation that
``dancedata stats`` computed over the training split, each with the array's row shape
(e.g. (24, 4)), to normalise a window with ``compute.normalization.normalize`` and undo it with
``denormalize`` before export.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from dancedata.errors import StoreError

__all__ = ["ArrayStats", "normalization"]


@dataclass(frozen=True)
class ArrayStats:
    """Mean and std of one array over a split, each of the array's row shape (float64)."""

    array: str
    mean: np.ndarray
    std: np.ndarray
    n_frames: int


def normalization(reader, array: str) -> ArrayStats:  # noqa: ANN001 - any _SequenceReader
    """The stored statistics of ``array``; StoreError naming ``dancedata stats`` when absent."""
    if not reader.has_table("normalization"):
        raise StoreError(
            f"version {reader.version} has no normalization table: run `dancedata stats "
            f"{reader.path} --arrays {array}`",
            reader.path,
        )
    rows = reader.table("normalization").to_pylist()
    mine = sorted((r for r in rows if r["array"] == array), key=lambda r: r["column"])
    if not mine:
        have = sorted({r["array"] for r in rows})
        raise StoreError(
            f"the normalization table has no {array!r} (it has {', '.join(have)})", reader.path
        )
    try:
        shape = tuple(int(d) for d in mine[0]["row_shape"].split(",") if d)
    except ValueError:
        raise StoreError(
            f"normalization row_shape of {array!r} is not a shape", reader.path
        ) from None
    if [r["column"] for r in mine] != list(range(len(mine))) or int(np.prod(shape)) != len(mine):
        raise StoreError(
            f"the normalization rows of {array!r} do not cover its columns", reader.path
        )
    mean = np.array([r["mean"] for r in mine], dtype=np.float64).reshape(shape)
    std = np.array([r["std"] for r in mine], dtype=np.float64).reshape(shape)
    return ArrayStats(array, mean, std, int(mine[0]["n_frames"]))
