"""Which SMPL-24 rest skeleton joint positions come from: a model file, or the built-in table.

Every command that turns SMPL rotations into joint positions (featurize's ``positions`` family,
``evaluate``, ``experiment run``, ``render``, ``export bvh``) asks :func:`smpl_skeleton` with the
model file it was given (or None). A model file, when given, wins; without one the built-in
``edge_smpl_offsets`` skeleton (:mod:`dancedata.compute.smpl_skeleton`) is used, so no licensed
file is needed. The choice is named in every record: ``skeleton`` is ``"edge_smpl_offsets"`` or
``"sha256:<hex>"`` of the model file.
"""

from __future__ import annotations

import hashlib
import os
from dataclasses import dataclass
from functools import lru_cache
from pathlib import Path
from typing import Any

import numpy as np

from dancedata.compute.smpl_joints import SmplJointModel, smpl_joint_positions
from dancedata.compute.smpl_skeleton import EDGE_SMPL_SKELETON, SMPL24_PARENTS
from dancedata.errors import InputError

__all__ = ["SmplSkeleton", "skeleton_name", "smpl_skeleton"]


@dataclass(frozen=True, eq=False)
class SmplSkeleton:
    """The rest skeleton of one run and how to name it.

    Attributes:
        model: what poses joints (an SMPL model file's joints, or the built-in table).
        name: ``"edge_smpl_offsets"`` or ``"sha256:<hex>"`` of the model file.
        file: the model file's name (None for the built-in skeleton).
        sha256: the model file's sha256 (None for the built-in skeleton).
    """

    model: SmplJointModel
    name: str
    file: str | None = None
    sha256: str | None = None

    @property
    def builtin(self) -> bool:
        return self.file is None

    def record(self) -> dict[str, Any]:
        """What a result records about the skeleton (JSON-ready)."""
        return {
            "skeleton": self.name,
            "root": "trans" if self.builtin else "J0 + trans",
            "betas": "zeros",
            "units": "m",
            "smpl_model": None if self.builtin else {"file": self.file, "sha256": self.sha256},
        }

    def positions(self, axis_angle: np.ndarray, trans: np.ndarray) -> np.ndarray:
        """(F, 24, 3) joint positions in metres from (F, 24, 3) axis-angle and (F, 3) trans."""
        return smpl_joint_positions(self.model, axis_angle, trans)


@lru_cache(maxsize=8)
def _sha256(path: str, mtime_ns: int, size: int) -> str:
    digest = hashlib.sha256()
    with open(path, "rb") as fh:
        for block in iter(lambda: fh.read(1 << 20), b""):
            digest.update(block)
    return digest.hexdigest()


def _file_sha256(path: str | Path) -> str:
    from dancedata.io.smpl_model import SMPL_MODEL_HELP

    file = Path(path)
    if not file.is_file():
        raise InputError(f"SMPL model file not found. {SMPL_MODEL_HELP}", file)
    stat = os.stat(file)
    return _sha256(str(file), stat.st_mtime_ns, stat.st_size)


def skeleton_name(model_path: str | Path | None) -> str:
    """The skeleton's name without loading the model: ``edge_smpl_offsets`` or the file's
    ``sha256:<hex>`` (InputError when the file does not exist)."""
    if not model_path:
        return EDGE_SMPL_SKELETON.name
    return f"sha256:{_file_sha256(model_path)}"


def smpl_skeleton(model_path: str | Path | None) -> SmplSkeleton:
    """The skeleton for ``model_path`` (None or "": the built-in ``edge_smpl_offsets``). Raises
    InputError naming the file when it is unreadable or its tree is not SMPL-24's."""
    if not model_path:
        return SmplSkeleton(EDGE_SMPL_SKELETON, EDGE_SMPL_SKELETON.name)
    from dancedata.io.smpl_model import cached_smpl_model

    model = cached_smpl_model(model_path)
    if tuple(model.parents) != SMPL24_PARENTS:
        raise InputError(
            f"the model's kinematic tree ({model.n_joints} joints) is not SMPL-24's", model_path
        )
    sha = _file_sha256(model_path)
    return SmplSkeleton(model, f"sha256:{sha}", Path(model_path).name, sha)
