"""A built-in SMPL-24 rest skeleton, so joint positions need no licensed model file.

EDGE (Tseng, Castellon and Liu, CVPR 2023; MIT licence) publishes the rest skeleton of SMPL as
24 joint offsets (``smpl_offsets`` in its ``vis.py``): each joint's rest offset from its parent
in metres, y up, betas 0. The numbers are facts of the SMPL rest pose, typed here as a table. The
convention is named ``edge_smpl_offsets`` wherever a result records it.

How it differs from an SMPL model file's joints (``dancedata.io.smpl_model``):

* the root joint sits *at* the translation (EDGE: root position = ``trans``), where SMPL puts it at
  ``J0 + trans`` (its regressed rest pelvis, about 0.2 m below the origin for betas 0): the two
  differ by that constant vector, the other joints' offsets are those of the model;
* betas are fixed at zero (no body shape);
* no model file: lengths are the table's (metres).

:class:`RestSkeleton` has what :func:`dancedata.compute.smpl_joints.smpl_joint_positions` needs
(``parents``, ``n_joints``, ``joint_offsets``), so the same solver poses it.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

__all__ = [
    "EDGE_SMPL_OFFSETS_M",
    "EDGE_SMPL_SKELETON",
    "EDGE_SMPL_SKELETON_NAME",
    "SMPL24_PARENTS",
    "RestSkeleton",
]

EDGE_SMPL_SKELETON_NAME = "edge_smpl_offsets"

# SMPL-24's kinematic tree (parent of each joint, -1 for the pelvis); equal to
# dancedata.compute.smpl's.
SMPL24_PARENTS: tuple[int, ...] = (
    -1, 0, 0, 0, 1, 2, 3, 4, 5, 6, 7, 8, 9, 9, 9, 12, 13, 14, 16, 17, 18, 19, 20, 21,
)  # fmt: skip

# Rest offset of each SMPL-24 joint from its parent (metres, y up, x to the body's left), as EDGE
# publishes them; row 0 (the pelvis) is zero: the root is placed at the translation.
EDGE_SMPL_OFFSETS_M = np.array(
    [
        [0.0, 0.0, 0.0],  # pelvis
        [0.05858135, -0.08228004, -0.01766408],  # left_hip
        [-0.06030973, -0.09051332, -0.01354254],  # right_hip
        [0.00443945, 0.12440352, -0.03838522],  # spine1
        [0.04345142, -0.38646945, 0.008037],  # left_knee
        [-0.04325663, -0.38368791, -0.00484304],  # right_knee
        [0.00448844, 0.1379564, 0.02682033],  # spine2
        [-0.01479032, -0.42687458, -0.037428],  # left_ankle
        [0.01905555, -0.4200455, -0.03456167],  # right_ankle
        [-0.00226458, 0.05603239, 0.00285505],  # spine3
        [0.04105436, -0.06028581, 0.12204243],  # left_foot
        [-0.03483987, -0.06210566, 0.13032329],  # right_foot
        [-0.0133902, 0.21163553, -0.03346758],  # neck
        [0.07170245, 0.11399969, -0.01889817],  # left_collar
        [-0.08295366, 0.11247234, -0.02370739],  # right_collar
        [0.01011321, 0.08893734, 0.05040987],  # head
        [0.12292141, 0.04520509, -0.019046],  # left_shoulder
        [-0.11322832, 0.04685326, -0.00847207],  # right_shoulder
        [0.2553319, -0.01564902, -0.02294649],  # left_elbow
        [-0.26012748, -0.01436928, -0.03126873],  # right_elbow
        [0.26570925, 0.01269811, -0.00737473],  # left_wrist
        [-0.26910836, 0.00679372, -0.00602676],  # right_wrist
        [0.08669055, -0.01063603, -0.01559429],  # left_hand
        [-0.0887537, -0.00865157, -0.01010708],  # right_hand
    ],
    dtype=np.float64,
)
EDGE_SMPL_OFFSETS_M.setflags(write=False)


@dataclass(frozen=True, eq=False)
class RestSkeleton:
    """A fixed rest skeleton: joint offsets from their parents (metres) and the tree.

    Attributes:
        name: the convention recorded with every number computed from it.
        parents: (J,) parent of each joint, -1 for the root.
        offsets: (J, 3) offset of each joint from its parent; the root's row is where the root
            sits relative to the translation (zero for ``edge_smpl_offsets``).
    """

    name: str
    parents: tuple[int, ...]
    offsets: np.ndarray

    @property
    def n_joints(self) -> int:
        return len(self.parents)

    def joint_offsets(self, betas: np.ndarray | None = None) -> np.ndarray:
        """(J, 3) rest offsets in metres. A fixed skeleton has no body shape: betas other than
        zeros raise ValueError."""
        if betas is not None and np.any(np.asarray(betas)):
            raise ValueError(f"the {self.name} skeleton has betas fixed at zero")
        return np.array(self.offsets, dtype=np.float64)


EDGE_SMPL_SKELETON = RestSkeleton(EDGE_SMPL_SKELETON_NAME, SMPL24_PARENTS, EDGE_SMPL_OFFSETS_M)
