"""The arrays ingest writes, as the store contract states them: the inputs of the motion families.

Each source (AIST++, BVH, video poses) stores some of these under ``motion``; a family names the
ones it reads in its ``inputs``. ``SOURCE_ARRAYS`` maps a source name to the arrays only that
source writes (``""``: arrays several sources write, checked by ``validate``). With the families'
``outputs`` these make the array part of ``schemas/store.schema.json``
(:mod:`dancedata.featurize.schema_arrays`).
"""

from __future__ import annotations

import numpy as np

from dancedata.featurize.family import ArraySpec

__all__ = ["BASE_ARRAYS", "SOURCE_ARRAYS", "source_array"]

_MASK = ("of", "codes")

SOURCE_ARRAYS: dict[str, tuple[ArraySpec, ...]] = {
    "": (
        ArraySpec("trans", (3,), np.float32),  # (F, 3) metres
        ArraySpec("axis_angle", ("J", 3), np.float32),  # (F, J, 3) radians
        ArraySpec("positions", ("J", 3), np.float32),  # (F, J, 3) metres, world joint positions
        ArraySpec("keypoints3d", (17, 3), np.float32),  # (F, 17, 3) metres
        ArraySpec("keypoints3d_optim", (17, 3), np.float32),
        ArraySpec("det_scores", (9,), np.float32),
    ),
    "video": (
        ArraySpec(
            "pose2d",
            (None, 3),
            np.float32,
            required_attrs=("units", "channels", "skeleton"),
            extension=True,
            nan_allowed=True,
        ),  # (F, J, 3): one tracked dancer, x, y pixels, confidence
        ArraySpec("pose2d_mask", (None,), np.uint8, required_attrs=_MASK, extension=True),
        ArraySpec("positions_mask", ("J",), np.uint8, required_attrs=_MASK, extension=True),
    ),
    "bvh": (
        ArraySpec(
            "local_translations",
            ("J", 3),
            np.float32,
            required_attrs=("units", "of"),
            extension=True,
            note="only for rigs with position channels below the root",
        ),
    ),
}

# Arrays written by ingest that no contract entry lists yet but families may read.
_UNLISTED: tuple[ArraySpec, ...] = (
    ArraySpec("euler", ("J", 3), np.float32),  # BVH: each joint's own order, radians
    ArraySpec("keypoints2d", (9, 17, 3), np.float32),  # AIST++: x, y pixels, confidence
)


def source_array(path: str) -> ArraySpec:
    """The declaration of the ingested array ``motion/<path>``."""
    for spec in (*(s for specs in SOURCE_ARRAYS.values() for s in specs), *_UNLISTED):
        if spec.path == path:
            return spec
    raise KeyError(path)


# Arrays a family may read, as ingest stores them (whichever of them the store has).
BASE_ARRAYS: tuple[str, ...] = (
    "axis_angle",
    "trans",
    "euler",
    "positions",
    "keypoints3d",
    "keypoints2d",
    "pose2d",
)
