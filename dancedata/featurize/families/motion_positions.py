"""The ``positions`` motion family: world joint positions (metres) by forward kinematics.

* SMPL-24 stores (AIST++): the rest joints of an SMPL model file (``--smpl-model`` or
  ``$DANCEDATA_SMPL_MODEL``; betas 0, as AIST++ has none) posed by ``axis_angle`` and moved by
  ``trans`` — see :mod:`dancedata.io.smpl_model`. No model ships with dancedata (licence); without
  one the built-in ``edge_smpl_offsets`` skeleton is used (:mod:`dancedata.compute.smpl_skeleton`:
  root at ``trans`` instead of ``J0 + trans``, betas 0). ``config()`` and the array's attrs name
  the skeleton (``skeleton``: ``edge_smpl_offsets`` or ``sha256:<hex>`` of the model file), so a
  change of model is a new fingerprint.
* Skeletons with offsets in their attrs (BVH stores): forward kinematics of ``axis_angle`` and
  ``trans`` over those offsets. BVH ingest already stores positions, so this is only needed to
  rebuild them; rigs with position channels below the root stored theirs at ingest from the
  per-frame joint translations and are refused here.

Subclasses :class:`~dancedata.featurize.families.motion_base.MotionFamily` and registers itself
(:func:`~dancedata.featurize.family.register_family`).
"""

from __future__ import annotations

from functools import lru_cache
from pathlib import Path
from typing import Any

import numpy as np

from dancedata.compute.fk import forward_kinematics
from dancedata.compute.rotations import axis_angle_to_rotmat
from dancedata.compute.smpl import SMPL_JOINTS
from dancedata.errors import InputError
from dancedata.featurize.families.motion_base import (
    ArraySpec,
    MotionBatch,
    MotionFamily,
    MotionSettings,
)
from dancedata.featurize.family import register_family
from dancedata.featurize.source_arrays import source_array
from dancedata.io.smpl_model import SMPL_MODEL_HELP
from dancedata.ops.smpl_skeletons import skeleton_name, smpl_skeleton

__all__ = ["PositionsFamily", "smpl_model_identity"]


@lru_cache(maxsize=8)
def _sha256(path: str, mtime_ns: int, size: int) -> str:
    from dancedata.store.checksums import sha256_file

    return sha256_file(path)


def smpl_model_identity(path: str | None) -> dict[str, Any] | None:
    """File name and sha256 of the SMPL model (fingerprinted), or None without one."""
    if not path:
        return None
    file = Path(path)
    if not file.is_file():
        raise InputError(f"SMPL model file not found. {SMPL_MODEL_HELP}", file)
    stat = file.stat()
    return {"file": file.name, "sha256": _sha256(str(file), stat.st_mtime_ns, stat.st_size)}


def _is_smpl(skeleton: dict[str, Any]) -> bool:
    joints = tuple(skeleton.get("joints") or ())
    return joints == SMPL_JOINTS or (skeleton.get("name") == "smpl24" and len(joints) == 24)


@register_family("positions")
class PositionsFamily(MotionFamily):
    """World joint positions from joint rotations and the root translation."""

    inputs = (source_array("axis_angle"), source_array("trans"))
    outputs = (source_array("positions"),)

    def arrays(self, n_joints: int, settings: MotionSettings) -> list[ArraySpec]:
        attrs: dict[str, Any] = {"units": "m", "method": "forward kinematics"}
        model = smpl_model_identity(settings.smpl_model)
        if model is not None:
            attrs["smpl_model"] = model
        attrs["smpl_skeleton"] = skeleton_name(settings.smpl_model)  # SMPL-24 stores only
        return [ArraySpec("positions", (n_joints, 3), np.float32, attrs)]

    def compute(self, batch: MotionBatch, settings: MotionSettings) -> dict[str, np.ndarray]:
        skeleton = batch.attrs.get("skeleton") or {}
        axis_angle, trans = batch.arrays["axis_angle"], batch.arrays["trans"]
        if _is_smpl(skeleton):
            rest = smpl_skeleton(settings.smpl_model)  # a model file wins; else edge_smpl_offsets
            parents = tuple(int(p) for p in skeleton.get("parents") or rest.model.parents)
            if tuple(rest.model.parents) != parents:
                raise InputError(
                    f"the {rest.name} kinematic tree ({rest.model.n_joints} joints) is not the "
                    "store's SMPL-24 tree",
                    settings.smpl_model,
                )
            return {"positions": rest.positions(axis_angle, trans)}
        if skeleton.get("offsets") is not None:
            if _has_joint_translations(skeleton):
                raise InputError(
                    "this rig has position channels below the root; its positions were computed "
                    "at ingest from the per-frame joint translations and are already stored: "
                    "leave 'positions' out"
                )
            offsets = np.asarray(skeleton["offsets"], dtype=np.float64)
            positions = forward_kinematics(
                skeleton["parents"], offsets, axis_angle_to_rotmat(axis_angle), trans
            )
            return {"positions": positions}
        raise InputError(
            f"cannot compute positions for skeleton {skeleton.get('name')!r}: it is not SMPL-24 "
            "and its attrs hold no offsets"
        )

    def config(self, settings: MotionSettings) -> dict[str, Any]:
        # ``skeleton`` names the rest skeleton of SMPL-24 stores; other rigs use the offsets of
        # their own skeleton attrs (fingerprinted with the parent version).
        return {
            "smpl_model": smpl_model_identity(settings.smpl_model),
            "betas": "zeros",
            "skeleton": skeleton_name(settings.smpl_model),
        }


def _has_joint_translations(skeleton: dict[str, Any]) -> bool:
    channels = skeleton.get("channels") or []
    return any(any(c.endswith("position") for c in chans) for chans in channels[1:])
