"""The motion arrays and attrs of a BVH store version.

:class:`BvhRig` holds the store's one skeleton and frame rate (from the parent when appending,
else from the first file) and refuses files that differ; :func:`bvh_array_specs` declares the
base arrays (float32, one row per frame) the engine streams each file's rows into.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from dancedata.errors import InputError
from dancedata.ingest.bvh.motion import BvhMotion
from dancedata.ingest.source import FrameArrayTarget, StoredArray
from dancedata.io.bvh import BvhSkeleton
from dancedata.io.bvh_attrs import skeleton_attrs, skeleton_from_attrs, skeleton_mismatch
from dancedata.store.arrays import CHUNK_FRAMES
from dancedata.store.reader import _VersionReader

__all__ = ["SOURCE", "BvhRig", "bvh_array_specs", "copy_parent_frames", "motion_arrays"]

SOURCE = "bvh"
_FPS_RTOL = 1e-6

# name → (row shape with None for the joint count, attrs)
_ARRAYS: dict[str, tuple[tuple[int | None, ...], dict[str, Any]]] = {
    "trans": ((3,), {"units": "m", "of": "root joint position (its position channels)"}),
    "axis_angle": ((None, 3), {"units": "rad"}),
    "euler": ((None, 3), {"units": "rad", "branch": "as in the file (winding kept)"}),
    "positions": ((None, 3), {"units": "m", "method": "forward kinematics of the channels"}),
    "local_translations": (
        (None, 3),
        {
            "units": "m",
            "of": "each joint's per-frame translation from its parent: its OFFSET, replaced "
            "by its position channels (root: = trans)",
        },
    ),
}


def bvh_array_specs(skeleton: BvhSkeleton, translations: bool) -> list[StoredArray]:
    """The base arrays of a BVH store with this skeleton (``local_translations`` only for rigs
    with position channels below the root)."""
    orders = list(skeleton.rotation_orders)
    specs = []
    for name, (shape, attrs) in _ARRAYS.items():
        if name == "local_translations" and not translations:
            continue
        row = tuple(skeleton.n_joints if d is None else d for d in shape)
        extra = {"order": orders} if name == "euler" else {}
        specs.append(StoredArray(name, row, np.float32, attrs=attrs | extra))
    return specs


def motion_arrays(motion: BvhMotion) -> dict[str, np.ndarray]:
    """A processed file's rows of the base arrays."""
    arrays = {
        "trans": motion.trans,
        "axis_angle": motion.axis_angle,
        "euler": motion.euler,
        "positions": motion.positions,
    }
    if motion.local_translations is not None:
        arrays["local_translations"] = motion.local_translations
    return arrays


class BvhRig:
    """The store's one skeleton and frame rate: from the version appended to, else from the
    first file accepted; files that differ are refused (:meth:`check`)."""

    def __init__(self, up_axis: str, atol_m: float) -> None:
        self.up_axis = up_axis
        self.atol_m = atol_m
        self.skeleton: BvhSkeleton | None = None
        self.fps: float | None = None
        self.attrs: dict[str, Any] = {}
        self.translations = False
        self.skeleton_from = ""  # the file (or version) the store's skeleton was taken from

    def adopt_parent(self, reader: _VersionReader) -> None:
        """Take skeleton, rate and attrs from the BVH version appended to."""
        self.attrs = reader.group_attrs("motion")
        self.skeleton = skeleton_from_attrs(self.attrs["skeleton"])
        self.fps = float(self.attrs["fps"])
        self.skeleton_from = f"version {reader.version} ({self.attrs['skeleton'].get('name')})"
        self.translations = reader.has_array("motion/local_translations")

    def check(self, motion: BvhMotion, path: Any) -> None:
        """Raise InputError when ``motion`` does not fit the store (skeleton, frame rate)."""
        if self.skeleton is not None:
            problem = skeleton_mismatch(self.skeleton, motion.clip.skeleton, self.atol_m)
            if problem is not None:
                raise InputError(
                    f"different skeleton from {self.skeleton_from}: {problem}; a store holds "
                    "one skeleton, so ingest this file into another store",
                    path,
                )
        if self.fps is not None and abs(motion.fps - self.fps) > _FPS_RTOL * self.fps:
            raise InputError(
                f"frame rate {motion.fps:g} fps differs from the store's {self.fps:g}; pass "
                f"--fps {self.fps:g} to resample",
                path,
            )

    def adopt_first(
        self, motion: BvhMotion, seq_id: str, units_name: str, metres: float, path: Any
    ) -> None:
        """The first file accepted into a new store sets its skeleton, rate and attrs."""
        if self.skeleton is not None:
            return
        self.skeleton, self.fps = motion.clip.skeleton, motion.fps
        self.skeleton_from = str(path if path is not None else seq_id)
        self.translations = motion.local_translations is not None
        self.attrs = {
            "fps": self.fps,
            "up_axis": self.up_axis,
            "source": SOURCE,
            "skeleton": skeleton_attrs(self.skeleton, f"bvh:{seq_id}", units_name, metres),
            "euler_orders": list(self.skeleton.rotation_orders),
        }

    def array_specs(self) -> list[StoredArray]:
        if self.skeleton is None:
            raise ValueError("no skeleton yet")
        return bvh_array_specs(self.skeleton, self.translations)


def copy_parent_frames(
    reader: _VersionReader, target: FrameArrayTarget, specs: list[StoredArray], n_frames: int
) -> None:
    """Declare ``specs`` on ``target`` and copy the parent's first ``n_frames`` frames of them,
    chunk by chunk."""
    target.declare(specs)
    arrays = {spec.name: reader.array(f"motion/{spec.name}") for spec in specs}
    for start in range(0, n_frames, CHUNK_FRAMES):
        stop = min(n_frames, start + CHUNK_FRAMES)
        target.append({name: np.asarray(array[start:stop]) for name, array in arrays.items()})
