"""Motion feature families: each computes a set of ``motion/...`` arrays from a batch of whole
sequences.

featurize reads the motion in batches of consecutive *whole* sequences (about one zarr chunk of
frames each), so a family can use neighbouring frames (velocities, sign continuity) without
state carried between batches, and batches are independent work units. A family declares the
arrays it writes and returns them with one row per frame of the batch.

Every family registers itself (``@register_family``, :mod:`dancedata.featurize.family`); the
registry loads every ``motion*`` module of ``featurize/families/``. This module holds the
``rotations`` family and the default set, and keeps :data:`FAMILIES` (the registered motion
families) importable. To add a family, subclass :class:`MotionFamily` in a new
``motion_<name>.py`` module and decorate it with ``@register_family("<name>")``.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from dancedata.compute.motion_representations import (
    KNOWN_REPRESENTATIONS,
    representation_attrs,
    representations_from_axis_angle,
    row_shape,
)
from dancedata.featurize.families.motion_base import (
    BASE_ARRAYS,
    ArraySpec,
    MotionBatch,
    MotionFamily,
    MotionSettings,
)
from dancedata.featurize.family import register_family, registered
from dancedata.featurize.source_arrays import source_array

# The base names stay importable from here (their home before the registry was split off).
__all__ = [
    "BASE_ARRAYS",
    "DEFAULT_FAMILIES",
    "ArraySpec",
    "MotionBatch",
    "MotionFamily",
    "MotionSettings",
    "RotationsFamily",
]


def _rotation_outputs() -> tuple[ArraySpec, ...]:
    zhou = "Zhou et al. 2019: first two COLUMNS of R, (r00, r10, r20, r01, r11, r21)"
    rows = (
        "featurize --representations ...,rot6d_rows: first two ROWS of R, (r00, r01, r02, r10, "
        "r11, r12), as pytorch3d matrix_to_rotation_6d and EDGE; decoding one layout as the "
        "other inverts the rotation"
    )
    declared = {
        "rotmat": ArraySpec("rotmat", ("J", 3, 3), np.float32),
        "euler": ArraySpec("euler", ("J", 3), np.float32, required_attrs=("order",)),
        "quat": ArraySpec("quat", ("J", 4), np.float32, required_attrs=("quat_order",)),
        "rot6d": ArraySpec(
            "rot6d", ("J", 6), np.float32, required_attrs=("rot6d_layout",), note=zhou
        ),
        "rot6d_rows": ArraySpec(
            "rot6d_rows", ("J", 6), np.float32, required_attrs=("rot6d_layout",), note=rows
        ),
    }
    return tuple(declared[name] for name in KNOWN_REPRESENTATIONS)


@register_family("rotations")
class RotationsFamily(MotionFamily):
    """rotmat, euler, quat (wxyz, sign-continuous within each sequence), rot6d (Zhou's
    columns) and, on request, rot6d_rows (pytorch3d's and EDGE's rows).

    On a BVH store whose ``euler`` (the file's own channels, stored at ingest) is already in
    the asked orders, ``euler`` is kept as it is rather than re-derived from ``axis_angle``: the
    same rotations, but the source's angle triples and branch, so that ``export bvh`` after
    featurize writes the channels as read (within float32 rounding, 7e-6 degrees), not the
    principal branch of a float32 round trip (up to 4e-5 degrees near gimbal lock, 360 degrees
    where the file winds)."""

    inputs = (source_array("axis_angle"),)
    optional_inputs = (source_array("euler"),)
    outputs = _rotation_outputs()

    def arrays(self, n_joints: int, settings: MotionSettings) -> list[ArraySpec]:
        return [
            ArraySpec(
                name,
                row_shape(name, n_joints),
                np.float32,
                representation_attrs(name, settings.euler_order),
            )
            for name in settings.representations
        ]

    def compute(self, batch: MotionBatch, settings: MotionSettings) -> dict[str, np.ndarray]:
        # One compiled pass writes the stored float32 arrays directly, quaternions
        # sign-continuous within each sequence (the float64 numbers rounded once).
        keep_euler = "euler" in settings.representations and _source_euler_fits(batch, settings)
        names = [n for n in settings.representations if not (keep_euler and n == "euler")]
        reps = representations_from_axis_angle(
            batch.axis_angle, names, settings.euler_order, dtype=np.float32, bounds=batch.bounds
        )
        if keep_euler:
            reps["euler"] = batch.arrays["euler"]
        return {name: reps[name] for name in settings.representations}

    def config(self, settings: MotionSettings) -> dict[str, Any]:
        return {
            "representations": sorted(settings.representations),
            "euler_order": settings.euler_order,
            "euler_from": "the ingested motion/euler (BVH channels) when its per-joint orders "
            "are euler_order, else axis_angle",
        }


def _source_euler_fits(batch: MotionBatch, settings: MotionSettings) -> bool:
    """The batch holds the source Euler channels of a BVH store, in the orders asked for."""
    orders = batch.attrs.get("euler_orders")
    return (
        "euler" in batch.arrays
        and batch.attrs.get("source") == "bvh"
        and isinstance(orders, list)
        and list(settings.euler_order) == orders
    )


DEFAULT_FAMILIES: tuple[str, ...] = ("rotations",)


def __getattr__(name: str) -> Any:
    """``FAMILIES``: the registered motion families (every motion* module of families/), by name."""
    if name == "FAMILIES":
        return registered("motion")
    raise AttributeError(name)
