"""Joint positions to draw for one sequence, from whatever the store holds (or a generated file).

Sources, and the order ``source="auto"`` tries them in:

1. ``smpl``: SMPL joints (24, metres, y-up) posed from ``motion/axis_angle`` and ``motion/trans``
   about an SMPL model file's rest joints (``smpl_model``; :mod:`dancedata.io.smpl_model`) or,
   without one, the built-in ``edge_smpl_offsets`` skeleton
   (:mod:`dancedata.ops.smpl_skeletons`).
   Chosen first when a model is given and the store's skeleton is SMPL-24; without a model,
   after ``keypoints3d`` and ``positions`` (before ``fk`` and ``pose2d``).
2. ``keypoints3d``: AIST++ COCO-17 keypoints (metres, y-up; NaN where not triangulated).
3. ``positions``: ``motion/positions`` (BVH forward kinematics at ingest or featurize's positions
   family; 3-d joints from video CSV), in metres.
4. ``fk``: forward kinematics of the stored rotations over the skeleton's ``offsets`` (BVH
   stores without positions), with per-frame joint translations when stored.
5. ``pose2d``: video 2-d poses in the source video's pixels (x right, y down), NaN where missing.

The up axis comes from the ``motion`` group attrs (``up_axis``; AIST++ and BVH: ``y``); see
:mod:`dancedata.compute.camera` for how each kind is put on screen.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from dancedata.errors import InputError, StoreError

if TYPE_CHECKING:
    from dancedata.read.loader import DanceStore

__all__ = ["SOURCES", "SkeletonTrack", "load_generated", "load_skeleton"]

SOURCES = ("auto", "smpl", "keypoints3d", "positions", "fk", "pose2d")
GENERATED_SUFFIXES = (".npy", ".npz", ".pkl")


@dataclass(frozen=True)
class SkeletonTrack:
    """Joint positions of one sequence, ready to project.

    Attributes:
        positions: (F, J, D) float32, D = 3 (world) or 2 (image pixels); NaN: not drawn.
        parents: (J,) parent of each joint, -1 for a root (bones join a joint to its parent).
        joints: joint names (for left/right colours), or empty.
        fps: frames per second.
        kind: "world" or "image".
        up_axis: the up axis of world coordinates (``y``, ``-y``, ``z``, ...).
        source: which source the positions came from (see the module docstring).
        label: a short name shown on the panel.
    """

    positions: np.ndarray
    parents: tuple[int, ...]
    joints: tuple[str, ...]
    fps: float
    kind: str
    up_axis: str
    source: str
    label: str

    @property
    def n_frames(self) -> int:
        return int(self.positions.shape[0])


def _slice(store: DanceStore, seq_id: str, name: str) -> np.ndarray:
    row = store.sequence(seq_id)
    return np.asarray(store.zarr(f"motion/{name}")[row["frame_start"] : row["frame_stop"]])


def _skeleton_of(store: DanceStore, name: str, fallback: dict[str, Any]) -> dict[str, Any]:
    attrs = dict(store.zarr(f"motion/{name}").attrs)
    skeleton = attrs.get("skeleton")
    return skeleton if isinstance(skeleton, dict) and skeleton.get("parents") else fallback


def _is_smpl(skeleton: dict[str, Any]) -> bool:
    from dancedata.compute.smpl import SMPL_JOINTS

    joints = tuple(skeleton.get("joints") or ())
    return joints == SMPL_JOINTS or (skeleton.get("name") == "smpl24" and len(joints) == 24)


def _track(
    positions: np.ndarray,
    skeleton: dict[str, Any],
    fps: float,
    kind: str,
    up: str,
    source: str,
    label: str,
) -> SkeletonTrack:
    parents = tuple(int(p) for p in skeleton.get("parents") or ())
    if len(parents) != positions.shape[1]:
        raise StoreError(
            f"the {source} array has {positions.shape[1]} joints but its skeleton lists "
            f"{len(parents)} parents"
        )
    joints = tuple(str(j) for j in skeleton.get("joints") or ())
    return SkeletonTrack(
        positions=np.asarray(positions, dtype=np.float32),
        parents=parents,
        joints=joints if len(joints) == len(parents) else (),
        fps=float(fps),
        kind=kind,
        up_axis=up,
        source=source,
        label=label,
    )


def _choose(store: DanceStore, motion: dict[str, Any], smpl_model: str | Path | None) -> str:
    has = store.has_array
    skeleton = motion.get("skeleton") or {}
    if smpl_model and has("motion/axis_angle") and _is_smpl(skeleton):
        return "smpl"
    for source in ("keypoints3d", "positions"):
        if has(f"motion/{source}"):
            return source
    if has("motion/axis_angle") and _is_smpl(skeleton):
        return "smpl"  # the built-in edge_smpl_offsets skeleton
    if skeleton.get("offsets") is not None and has("motion/axis_angle"):
        return "fk"
    if has("motion/pose2d"):
        return "pose2d"
    raise StoreError("this store holds no joint positions to draw", store.path)


def load_skeleton(
    store: DanceStore,
    seq_id: str,
    source: str = "auto",
    smpl_model: str | Path | None = None,
) -> SkeletonTrack:
    """The joint positions of ``seq_id`` from ``source`` (module docstring; "auto": the first
    available in that order).

    Raises:
        StoreError: when the store lacks the source's arrays or ``seq_id``.
        InputError: for an unknown source or an unreadable SMPL model file.
    """
    if source not in SOURCES:
        raise InputError(f"source must be one of {', '.join(SOURCES)}, not {source!r}")
    row = store.sequence(seq_id)
    motion = store.group_attrs("motion")
    if source == "auto":
        source = _choose(store, motion, smpl_model)
    elif source in ("keypoints3d", "positions", "pose2d") and not store.has_array(
        f"motion/{source}"
    ):
        raise StoreError(f"this store has no motion/{source}", store.path)
    fps = float(row.get("fps") or motion.get("fps") or 0)
    if not fps > 0:
        raise StoreError(f"sequence {seq_id} has no frame rate", store.path)
    up = str(motion.get("up_axis") or "y")
    skeleton = motion.get("skeleton") or {}
    label = f"{seq_id} ({source})"
    if source == "pose2d":
        pose = _slice(store, seq_id, "pose2d")
        xy = pose[..., :2].astype(np.float32)
        xy[pose[..., 2] <= 0] = np.nan
        return _track(
            xy, _skeleton_of(store, "pose2d", skeleton), fps, "image", "-y", source, label
        )
    if source in ("keypoints3d", "positions"):
        values = _slice(store, seq_id, source)
        return _track(
            values, _skeleton_of(store, source, skeleton), fps, "world", up, source, label
        )
    axis_angle = _slice(store, seq_id, "axis_angle")
    trans = _slice(store, seq_id, "trans")
    if source == "smpl":
        from dancedata.ops.smpl_skeletons import smpl_skeleton

        rest = smpl_skeleton(smpl_model)  # a model file wins; else edge_smpl_offsets
        positions = rest.positions(axis_angle, trans)
        skel = {"parents": list(rest.model.parents), "joints": skeleton.get("joints") or []}
        label = f"{seq_id} (smpl, {rest.file or rest.name})"
        return _track(positions, skel, fps, "world", up, source, label)
    offsets = skeleton.get("offsets")
    if offsets is None:
        raise StoreError("this store's skeleton has no offsets for forward kinematics", store.path)
    from dancedata.compute.fk import forward_kinematics
    from dancedata.compute.rotations import axis_angle_to_rotmat

    joint_translations = None
    if store.has_array("motion/local_translations"):
        joint_translations = _slice(store, seq_id, "local_translations")
    positions = forward_kinematics(
        skeleton["parents"],
        np.asarray(offsets, dtype=np.float64),
        axis_angle_to_rotmat(axis_angle),
        trans,
        joint_translations=joint_translations,
    )
    return _track(positions, skeleton, fps, "world", up, source, label)


# ----------------------------------------------------------------------------- generated motion


def _generated_file(path: Path, seq_id: str) -> Path:
    """``path`` itself, or its file for ``seq_id`` matched by exact name
    (:func:`dancedata.io.generated_motion.find_generated_file`: never a glob or a path)."""
    from dancedata.io.generated_motion import find_generated_file

    if path.is_file():
        return path
    if path.is_dir():
        found = find_generated_file(path, seq_id)
        if found is not None:
            return found
        raise InputError(
            f"no generated motion for {seq_id} (looked for {seq_id}"
            f"{{{','.join(GENERATED_SUFFIXES)}}})",
            path,
        )
    raise InputError("generated motion file or folder not found", path)


def _smpl_generated(
    poses: np.ndarray, trans: np.ndarray, smpl_model: str | Path | None, path: Path
) -> np.ndarray:
    """SMPL rotations → joints about the model file's rest joints, else edge_smpl_offsets."""
    from dancedata.ops.smpl_skeletons import smpl_skeleton

    poses = np.asarray(poses, dtype=np.float64)
    if poses.ndim < 2 or poses[0].size != 72:
        raise InputError(f"SMPL poses must be (F, 72) or (F, 24, 3), got {poses.shape}", path)
    poses = poses.reshape(poses.shape[0], 24, 3)
    return smpl_skeleton(smpl_model).positions(poses, np.asarray(trans, dtype=np.float64))


def _fact_rows(rows: np.ndarray, smpl_model: str | Path | None, path: Path) -> np.ndarray:
    """225-d FACT rows (6 zeros, trans 3, rotmat 216) → SMPL joints."""
    from dancedata.compute.rotations import rotmat_to_axis_angle

    trans = rows[:, 6:9]
    rotmat = rows[:, 9:225].reshape(-1, 24, 3, 3)
    return _smpl_generated(rotmat_to_axis_angle(rotmat), trans, smpl_model, path)


def load_generated(
    path: str | Path,
    seq_id: str,
    like: SkeletonTrack,
    smpl_model: str | Path | None = None,
    fps: float | None = None,
    up_axis: str = "y",
) -> SkeletonTrack:
    """Generated motion for ``seq_id``: ``path`` itself, or ``path/<seq_id>.{npy,npz,pkl}``.

    Layouts read (metres, y-up unless ``up_axis``): joint positions (F, J, 3) or (1, F, J, 3)
    (``.npy``, or the key ``positions``/``full_pose`` of an ``.npz``/``.pkl``); FACT 225-d rows
    (F, 225) or (1, F, 225); SMPL ``smpl_poses`` (F, 72) with ``smpl_trans`` (F, 3) (divided by
    ``smpl_scaling`` when present, as AIST++ does). Rotations are posed about ``smpl_model``'s rest
    joints, else the built-in ``edge_smpl_offsets`` skeleton. Bones: SMPL-24
    for 24 joints, else ``like``'s skeleton when the joint counts match. ``fps``: default
    ``like.fps``.
    """
    from dancedata.io.generated_motion import generated_frame_limit, read_generated_arrays

    file = _generated_file(Path(path), seq_id)
    limit = generated_frame_limit(len(like.positions), fps or like.fps, like.fps)
    data = read_generated_arrays(file, limit)  # shapes checked before anything is loaded
    array = data.get("array")
    for key in ("positions", "full_pose"):
        if array is None and key in data:
            array = data[key]
    if array is not None and array.ndim >= 2 and array.shape[0] == 1 and array.ndim in (3, 4):
        array = array[0]
    if array is not None and array.ndim == 3 and array.shape[2] == 3:
        positions = array.astype(np.float64)
    elif array is not None and array.ndim == 2 and array.shape[1] == 225:
        positions = _fact_rows(array.astype(np.float64), smpl_model, file)
    elif "smpl_poses" in data and "smpl_trans" in data:
        trans = np.asarray(data["smpl_trans"], dtype=np.float64)
        if "smpl_scaling" in data:
            trans = trans / float(np.asarray(data["smpl_scaling"]).reshape(-1)[0])
        positions = _smpl_generated(data["smpl_poses"], trans, smpl_model, file)
    else:
        shape = None if array is None else array.shape
        raise InputError(
            f"unknown generated-motion layout (array shape {shape}, keys {sorted(data)}): "
            "expected (F, J, 3) positions, (F, 225) FACT rows, or smpl_poses + smpl_trans",
            file,
        )
    n_joints = positions.shape[1]
    if n_joints == 24:
        from dancedata.compute.smpl import SMPL_JOINTS, SMPL_PARENTS

        skeleton = {"parents": list(SMPL_PARENTS), "joints": list(SMPL_JOINTS)}
    elif n_joints == len(like.parents):
        skeleton = {"parents": list(like.parents), "joints": list(like.joints)}
    else:
        raise InputError(
            f"generated motion has {n_joints} joints: bones are known for 24 (SMPL) or "
            f"{len(like.parents)} (the sequence's skeleton)",
            file,
        )
    return _track(
        positions,
        skeleton,
        float(fps or like.fps),
        "world",
        up_axis,
        "generated",
        f"{seq_id} (generated: {file.name})",
    )
