"""The motion arrays and attrs of a BVH store version, written one file at a time.

:class:`BvhArrayStream` holds the store's one skeleton and frame rate (from the parent when
appending, else from the first file), refuses files that differ, and streams each file's arrays
(float32) into frame-concatenated zarr arrays, so memory holds one file at a time.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from dancedata.errors import InputError
from dancedata.ingest.bvh_motion import BvhMotion
from dancedata.io.bvh import BvhSkeleton
from dancedata.io.bvh_attrs import skeleton_attrs, skeleton_from_attrs, skeleton_mismatch
from dancedata.store.arrays import CHUNK_FRAMES, FrameArrayWriter
from dancedata.store.reader import VersionReader
from dancedata.store.writer import VersionWriter

__all__ = ["SOURCE", "BvhArrayStream"]

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


class BvhArrayStream:
    """Base arrays of one version being written; see the module docstring."""

    def __init__(self, version: VersionWriter, up_axis: str, atol_m: float) -> None:
        self.version = version
        self.up_axis = up_axis
        self.atol_m = atol_m
        self.skeleton: BvhSkeleton | None = None
        self.fps: float | None = None
        self.attrs: dict[str, Any] = {}
        self.frames = 0
        self.skeleton_from = ""  # the file (or version) the store's skeleton was taken from
        self._writers: dict[str, FrameArrayWriter] = {}

    # -- set-up ------------------------------------------------------------------------------
    def _open(self, skeleton: BvhSkeleton, translations: bool) -> None:
        motion = self.version.zarr_group().require_group("motion")
        self.version.zarr_group().require_group("audio")
        orders = list(skeleton.rotation_orders)
        for name, (shape, attrs) in _ARRAYS.items():
            if name == "local_translations" and not translations:
                continue
            row = tuple(skeleton.n_joints if d is None else d for d in shape)
            extra = {"order": orders} if name == "euler" else {}
            self._writers[name] = FrameArrayWriter(
                motion, name, row, np.float32, attrs=attrs | extra
            )

    def copy_parent(self, reader: VersionReader, n_frames: int) -> None:
        """Take skeleton, rate and attrs from a BVH version and copy its ``n_frames`` frames of
        base arrays, chunk by chunk."""
        self.attrs = reader.group_attrs("motion")
        self.skeleton = skeleton_from_attrs(self.attrs["skeleton"])
        self.fps = float(self.attrs["fps"])
        self.skeleton_from = f"version {reader.version} ({self.attrs['skeleton'].get('name')})"
        self._open(self.skeleton, reader.has_array("motion/local_translations"))
        arrays = {name: reader.array(f"motion/{name}") for name in self._writers}
        for start in range(0, n_frames, CHUNK_FRAMES):
            stop = min(n_frames, start + CHUNK_FRAMES)
            for name, array in arrays.items():
                self._writers[name].append(np.asarray(array[start:stop]))
        self.frames = n_frames

    # -- files -------------------------------------------------------------------------------
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

    def add(
        self, motion: BvhMotion, seq_id: str, units_name: str, metres: float, path: Any = None
    ) -> int:
        """Append a checked file's arrays; returns its first frame in the store."""
        if self.skeleton is None:
            self.skeleton, self.fps = motion.clip.skeleton, motion.fps
            self.skeleton_from = str(path if path is not None else seq_id)
            self.attrs = {
                "fps": self.fps,
                "up_axis": self.up_axis,
                "source": SOURCE,
                "skeleton": skeleton_attrs(self.skeleton, f"bvh:{seq_id}", units_name, metres),
                "euler_orders": list(self.skeleton.rotation_orders),
            }
            self._open(self.skeleton, motion.local_translations is not None)
        arrays = {
            "trans": motion.trans,
            "axis_angle": motion.axis_angle,
            "euler": motion.euler,
            "positions": motion.positions,
            "local_translations": motion.local_translations,
        }
        for name, writer in self._writers.items():
            writer.append(arrays[name])
        start = self.frames
        self.frames += motion.n_frames
        return start

    def close(self) -> None:
        """Flush the arrays and write the motion attrs."""
        for writer in self._writers.values():
            writer.close()
        if self.attrs:
            self.version.zarr_group()["motion"].attrs.update(self.attrs)
