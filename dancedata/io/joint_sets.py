"""Joint sets of 3-d pose lifters, by name: what a joints CSV's header may use.

Besides OpenPose's BODY_25 and COCO-18 (``io.openpose``), video-to-3-d lifters write:

* **H36M-17** (Human3.6M's 17 joints as VideoPose3D, MotionBERT and most lifters order them),
  rooted at the pelvis; names as VideoPose3D (``Hip``, ``RHip``, ``RFoot``, ``Neck/Nose``, ...)
  or as I2L-MeshNet/Pose2Mesh (``Pelvis``, ``R_Hip``, ``R_Ankle``, ``Nose``, ...).
* **SPIN-24** (SPIN/VIBE's 24 ground-truth joints regressed from SMPL: LSP's 14, MPII's pelvis
  and thorax, H36M's spine, jaw and head, COCO's face), rooted at the pelvis.
* **HMR-19** (HMR's "cocoplus": LSP's 14 plus nose, eyes and ears), rooted at the neck, as LSP
  has no pelvis joint.

Each set lists its joints in the lifter's output order with the parent of each (a tree for
drawing bones and solving rotations). Names match ignoring case and every character that is not
a letter or digit, so ``R_Hip``, ``r hip`` and ``RHip`` are one name.
"""

from __future__ import annotations

import re
from dataclasses import dataclass

__all__ = ["H36M_17", "HMR_19", "LIFTER_SETS", "SPIN_24", "JointSet", "normalise_name"]


def normalise_name(name: str) -> str:
    """Lower case, letters and digits only: the form joint names are compared in."""
    return re.sub(r"[^a-z0-9]", "", name.lower())


@dataclass(frozen=True)
class JointSet:
    """A named joint layout: ``joints`` (canonical names, output order), ``parents`` (−1 for
    the root) and ``aliases`` (other spellings of the whole list, same order)."""

    name: str
    joints: tuple[str, ...]
    parents: tuple[int, ...]
    aliases: tuple[tuple[str, ...], ...] = ()

    def spellings(self) -> list[tuple[str, ...]]:
        return [self.joints, *self.aliases]

    def to_dict(self) -> dict:
        """The ``skeleton`` attribute of the contract: ``name``, ``joints``, ``parents``."""
        return {"name": self.name, "joints": list(self.joints), "parents": list(self.parents)}


H36M_17 = JointSet(
    name="h36m17",
    joints=(
        "Hip", "RHip", "RKnee", "RFoot", "LHip", "LKnee", "LFoot", "Spine", "Thorax",
        "Neck/Nose", "Head", "LShoulder", "LElbow", "LWrist", "RShoulder", "RElbow", "RWrist",
    ),
    parents=(-1, 0, 1, 2, 0, 4, 5, 0, 7, 8, 9, 8, 11, 12, 8, 14, 15),
    aliases=(
        (
            "Pelvis", "R_Hip", "R_Knee", "R_Ankle", "L_Hip", "L_Knee", "L_Ankle", "Torso",
            "Neck", "Nose", "Head", "L_Shoulder", "L_Elbow", "L_Wrist", "R_Shoulder",
            "R_Elbow", "R_Wrist",
        ),
    ),
)  # fmt: skip

SPIN_24 = JointSet(
    name="spin24",
    joints=(
        "Right Ankle", "Right Knee", "Right Hip", "Left Hip", "Left Knee", "Left Ankle",
        "Right Wrist", "Right Elbow", "Right Shoulder", "Left Shoulder", "Left Elbow",
        "Left Wrist", "Neck (LSP)", "Top of Head (LSP)", "Pelvis (MPII)", "Thorax (MPII)",
        "Spine (H36M)", "Jaw (H36M)", "Head (H36M)", "Nose", "Left Eye", "Right Eye",
        "Left Ear", "Right Ear",
    ),
    parents=(1, 2, 14, 14, 3, 4, 7, 8, 15, 15, 9, 10, 15, 18, -1, 16, 14, 12, 12, 18, 19, 19,
             20, 21),
)  # fmt: skip

HMR_19 = JointSet(
    name="hmr19",
    joints=(
        "R Ankle", "R Knee", "R Hip", "L Hip", "L Knee", "L Ankle", "R Wrist", "R Elbow",
        "R Shoulder", "L Shoulder", "L Elbow", "L Wrist", "Neck", "Head", "Nose", "L Eye",
        "R Eye", "L Ear", "R Ear",
    ),
    parents=(1, 2, 12, 12, 3, 4, 7, 8, 12, 12, 9, 10, -1, 12, 12, 14, 14, 15, 16),
    aliases=(
        (
            "R_Ankle", "R_Knee", "R_Hip", "L_Hip", "L_Knee", "L_Ankle", "R_Wrist", "R_Elbow",
            "R_Shoulder", "L_Shoulder", "L_Elbow", "L_Wrist", "Neck", "Head_top", "Nose",
            "L_Eye", "R_Eye", "L_Ear", "R_Ear",
        ),
    ),
)  # fmt: skip

LIFTER_SETS: dict[str, JointSet] = {s.name: s for s in (H36M_17, SPIN_24, HMR_19)}
