"""Write a stored sequence back to BVH: read the store, solve the clip, write the file.

The pipeline step of BVH export (issue 15 item 3): store access, rest offsets and rotations are
here, the file text is written by :func:`dancedata.io.bvh.write_bvh` from the plain clip.

Two layouts:

* **original** (stores from ``ingest bvh``): the skeleton attrs hold the file's hierarchy,
  OFFSETs, End Sites and every joint's channel list, so the file is rebuilt channel for channel.
  Angles come from ``motion/euler`` when its per-joint orders are the channels' (they are after
  ingest, and featurize keeps the ingested channels: the file's own triples and branch),
  else from ``motion/axis_angle``, converted in each joint's channel order and made continuous
  over time. Position channels come from ``motion/trans`` and, on rigs with position channels
  below the root, ``motion/local_translations``. Lengths are written in the file's own unit
  (``source_units``) unless told otherwise.
* **generated** (SMPL / AIST++ stores, and any skeleton without a channel layout): every joint
  gets three rotation channels in one order (default ZYX), the root also X/Y/Z position.
  OFFSETs come from the skeleton attrs when they hold any, else from ``motion/ik_rest_offsets``
  (rotations solved from joint positions by ``featurize --motion-families
  rotations_from_positions``; joints written parents first), else, for SMPL-24, from an SMPL model
  file's rest joints (betas 0) or, without one, from the built-in ``edge_smpl_offsets`` skeleton
  (:mod:`dancedata.compute.smpl_skeleton`; its root at the translation). The result's
  ``offsets_from`` names which. The root's position channels hold ``rest root + trans``.
  Default unit: centimetres.

Accuracy: stored angles are float32 radians, so written angles are within about 1.4e-5 degrees
of the source file for angles up to 4 rad (229 degrees); lengths within float32 rounding (about
6e-8 relative).
"""

from __future__ import annotations

import os
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from dancedata.compute.fk import topological_order
from dancedata.compute.rotations import axis_angle_to_rotmat
from dancedata.errors import InputError, StoreError
from dancedata.io.bvh import (
    BvhClip,
    BvhSkeleton,
    clip_from_arrays,
    make_skeleton,
    scale_clip,
    write_bvh,
)
from dancedata.io.bvh_attrs import is_bvh_skeleton, skeleton_from_attrs
from dancedata.ops.bvh_clip import clip_from_rotations
from dancedata.read.sequence_reader import known_ids
from dancedata.store.backend import StoreBackend
from dancedata.store.reader import _VersionReader

__all__ = ["BvhExportOptions", "BvhExportResult", "export_bvh", "sequence_clip"]


@dataclass
class BvhExportOptions:
    """Settings of one export.

    Attributes:
        version: store version to read (default: latest).
        units: length unit of the written file (m, cm, mm, in, ft, dm or metres per unit);
            None: the source file's unit for BVH stores, else cm.
        rotation_order: channel order of generated layouts (intrinsic, e.g. ZYX, ZXY).
        smpl_model: SMPL model file for the rest skeleton of SMPL stores (default:
            ``$DANCEDATA_SMPL_MODEL`` when set).
        precision: decimals written.
    """

    version: str | None = None
    units: str | None = None
    rotation_order: str = "ZYX"
    smpl_model: str | Path | None = None
    precision: int = 6


@dataclass
class BvhExportResult:
    """What was written, and from which stored arrays."""

    path: str
    seq_id: str
    version: str
    frames: int
    joints: int
    layout: str  # "original" or "generated"
    angles_from: str  # "euler" or "axis_angle"
    offsets_from: str
    units: str
    skipped: list[dict[str, str]] = field(default_factory=list)

    def message(self, command: str) -> str:
        return (
            f"{command}: wrote {self.path} ({self.seq_id} of {self.version}, {self.frames} "
            f"frames, {self.joints} joints, {self.layout} layout, offsets from "
            f"{self.offsets_from})"
        )

    def as_dict(self) -> dict[str, Any]:
        return {k: v for k, v in self.__dict__.items() if k != "skipped"}


def _sequence_row(reader: _VersionReader, seq_id: str) -> dict[str, Any]:
    rows = reader.table("sequences").to_pylist()
    for row in rows:
        if row["seq_id"] == seq_id:
            return row
    raise StoreError(
        f"no sequence {seq_id!r} in version {reader.version} "
        f"({known_ids(seq_id, [r['seq_id'] for r in rows])})",
        reader.path,
    )


def _units(name: str) -> tuple[str, float]:
    from dancedata.compute.bvh_units import parse_units

    unit = parse_units(name)
    return unit.name, unit.metres


def _original_clip(
    reader: _VersionReader, skel_attrs: dict[str, Any], f0: int, f1: int, frame_time: float
) -> tuple[BvhClip, str]:
    """The clip (metres) in the file's own layout, and which array gave the angles."""
    skel = skeleton_from_attrs(skel_attrs)
    trans = np.asarray(reader.array("motion/trans")[f0:f1], dtype=np.float64)
    n = trans.shape[0]
    if skel.has_position_channels[1:].any() and reader.has_array("motion/local_translations"):
        translations = np.asarray(reader.array("motion/local_translations")[f0:f1], np.float64)
    else:
        translations = np.broadcast_to(skel.offsets, (n, skel.n_joints, 3)).copy()
    translations[:, 0] = trans
    orders = list(skel.rotation_orders)
    if reader.has_array("motion/euler") and _orders(reader) == orders:
        euler = np.degrees(np.asarray(reader.array("motion/euler")[f0:f1], dtype=np.float64))
        return clip_from_arrays(skel, frame_time, euler, translations), "euler"
    rotmats = axis_angle_to_rotmat(_array(reader, "axis_angle", f0, f1))
    return clip_from_rotations(skel, frame_time, rotmats, translations), "axis_angle"


def _orders(reader: _VersionReader) -> list[str] | None:
    order = reader.array("motion/euler").attrs.get("order")
    return list(order) if isinstance(order, list) else None


def _array(reader: _VersionReader, name: str, f0: int, f1: int) -> np.ndarray:
    if not reader.has_array(f"motion/{name}"):
        raise StoreError(
            f"version {reader.version} has no motion/{name}; BVH export needs joint rotations "
            "(motion/axis_angle) and the root translation (motion/trans)"
            + (
                "; solve them from the joint positions first: dancedata featurize STORE "
                "--motion-families rotations_from_positions"
                if reader.has_array("motion/positions")
                else ""
            ),
            reader.path,
        )
    return np.asarray(reader.array(f"motion/{name}")[f0:f1], dtype=np.float64)


def _rest_offsets(
    skel_attrs: dict[str, Any], smpl_model: str | Path | None
) -> tuple[np.ndarray, str]:
    """Rest OFFSETs (metres) of a skeleton without a channel layout, and their source."""
    from dancedata.compute.smpl import SMPL_JOINTS
    from dancedata.io.smpl_model import SMPL_MODEL_ENV
    from dancedata.ops.smpl_skeletons import smpl_skeleton

    n = len(skel_attrs["joints"])
    if skel_attrs.get("offsets") is not None:
        return np.asarray(skel_attrs["offsets"], dtype=np.float64).reshape(n, 3), "skeleton attrs"
    is_smpl = tuple(skel_attrs["joints"]) == SMPL_JOINTS or skel_attrs.get("name") == "smpl24"
    if not is_smpl:
        raise StoreError(
            f"skeleton {skel_attrs.get('name')!r} has no offsets, so no BVH hierarchy can be "
            "written for it"
        )
    rest = smpl_skeleton(smpl_model or os.environ.get(SMPL_MODEL_ENV))  # a model file wins
    if rest.builtin:
        return rest.model.joint_offsets(), f"{rest.name} (built-in SMPL rest skeleton, betas 0)"
    return rest.model.joint_offsets(), f"SMPL model {rest.file} (betas 0)"


def _generated_clip(
    reader: _VersionReader,
    skel_attrs: dict[str, Any],
    f0: int,
    f1: int,
    frame_time: float,
    options: BvhExportOptions,
) -> tuple[BvhClip, str]:
    """A clip (metres) in a generated layout, and where its offsets came from."""
    names = list(skel_attrs["joints"])
    parents = [int(p) for p in skel_attrs["parents"]]
    axis_angle = _array(reader, "axis_angle", f0, f1)
    trans = _array(reader, "trans", f0, f1)
    if axis_angle.shape[1] != len(names):
        raise StoreError(
            f"motion/axis_angle has {axis_angle.shape[1]} joints, skeleton {len(names)}"
        )
    if skel_attrs.get("offsets") is None and reader.has_array("motion/ik_rest_offsets"):
        # rotations solved from positions (rotations_from_positions): the sequence's own rest
        # skeleton, and joints put parents first (BODY_25 / COCO-18 are not)
        offsets = np.asarray(reader.array("motion/ik_rest_offsets")[f0], dtype=np.float64)
        source = "rest skeleton solved from positions (motion/ik_rest_offsets)"
        order = topological_order(parents)
        where = {j: k for k, j in enumerate(order)}
        names, offsets, axis_angle = [names[j] for j in order], offsets[order], axis_angle[:, order]
        parents = [-1 if parents[j] < 0 else where[parents[j]] for j in order]
    else:
        offsets, source = _rest_offsets(skel_attrs, options.smpl_model)
    skel: BvhSkeleton = make_skeleton(names, parents, offsets, options.rotation_order, True)
    n = trans.shape[0]
    translations = np.broadcast_to(offsets, (n, len(names), 3)).copy()
    translations[:, 0] = offsets[0] + trans
    clip = clip_from_rotations(skel, frame_time, axis_angle_to_rotmat(axis_angle), translations)
    return clip, source


def sequence_clip(
    store: str | Path | StoreBackend, seq_id: str, options: BvhExportOptions | None = None
) -> tuple[BvhClip, BvhExportResult]:
    """The BVH clip (in the output unit) of one stored sequence, and a description of it."""
    options = options or BvhExportOptions()
    order = options.rotation_order.upper()
    if len(order) != 3 or sorted(order) != ["X", "Y", "Z"]:
        raise InputError(f"--rotation-order must be a permutation of XYZ, not {order!r}")
    reader = _VersionReader(store, options.version)
    row = _sequence_row(reader, seq_id)
    f0, f1 = int(row["frame_start"]), int(row["frame_stop"])
    attrs = reader.group_attrs("motion")
    fps = float(row.get("fps") or attrs.get("fps") or 0)
    frame_time = 1.0 / fps if fps > 0 else 0.0
    source_fps, source_time = row.get("source_fps"), row.get("source_frame_time_s")
    if source_fps and source_time and abs(float(source_fps) - fps) <= 1e-9 * fps:
        frame_time = float(source_time)  # not resampled: the file's Frame Time as written
    if not frame_time > 0:
        raise StoreError(f"sequence {seq_id!r} has no frame rate", reader.path)
    skel_attrs = attrs.get("skeleton") or {}
    if not skel_attrs.get("joints"):
        raise StoreError("the motion attrs name no skeleton", reader.path)
    if is_bvh_skeleton(skel_attrs):
        clip_m, angles_from = _original_clip(reader, skel_attrs, f0, f1, frame_time)
        layout, offsets_from = "original", "skeleton attrs (source file)"
        if options.units is None:
            unit_name, metres = skel_attrs["source_units"], float(skel_attrs["metres_per_unit"])
        else:
            unit_name, metres = _units(options.units)
    else:
        clip_m, offsets_from = _generated_clip(reader, skel_attrs, f0, f1, frame_time, options)
        layout, angles_from = "generated", "axis_angle"
        unit_name, metres = _units(options.units or "cm")
    clip = scale_clip(clip_m, 1.0 / metres)
    result = BvhExportResult(
        path="",
        seq_id=seq_id,
        version=reader.version,
        frames=clip.n_frames,
        joints=clip.skeleton.n_joints,
        layout=layout,
        angles_from=angles_from,
        offsets_from=offsets_from,
        units=unit_name,
    )
    return clip, result


def export_bvh(
    store: str | Path | StoreBackend,
    seq_id: str,
    out: str | Path,
    options: BvhExportOptions | None = None,
) -> BvhExportResult:
    """Write sequence ``seq_id`` of ``store`` to the BVH file ``out`` (atomically)."""
    options = options or BvhExportOptions()
    clip, result = sequence_clip(store, seq_id, options)
    out = Path(out)
    if not out.parent.is_dir():
        raise InputError("output folder does not exist", out.parent)
    write_bvh(clip, out, precision=options.precision)
    result.path = str(out)
    return result
