"""Interior joint angles from joint positions, for sources without joint rotations.

Video poses (``motion/pose2d``, ``motion/positions``) and AIST++ keypoints carry positions
only. The angle drawn for them is the *interior* angle at a hinge joint: the angle between the
bones to its parent and to its child, 180° for a straight limb, in the positions' own space (the
image plane for 2-d poses, so foreshortened). Pure functions: arrays in, arrays out.
"""

from __future__ import annotations

import re
from collections.abc import Sequence

import numpy as np

HINGE_PATTERN = re.compile(r"knee|elbow", re.IGNORECASE)


def hinge_triples(joints: Sequence[str], parents: Sequence[int]) -> list[tuple[str, int, int, int]]:
    """(name, parent, joint, child) for every joint whose name says knee or elbow and that has
    a parent and exactly one child in the skeleton; in skeleton order."""
    out = []
    for j, name in enumerate(joints):
        if not HINGE_PATTERN.search(str(name)) or parents[j] < 0:
            continue
        children = [c for c, p in enumerate(parents) if p == j]
        if len(children) == 1:
            out.append((str(name), int(parents[j]), j, children[0]))
    return out


def interior_angles_deg(points: np.ndarray, triples: Sequence[tuple[int, int, int]]) -> np.ndarray:
    """(F, K) angle in degrees at joint b between b→a and b→c for each (a, b, c) of
    ``triples``, from ``points`` (F, J, D) of any dimension D. NaN where a point is missing or
    a bone has zero length."""
    pts = np.asarray(points, dtype=np.float64)
    a, b, c = (np.array([t[i] for t in triples], dtype=np.int64) for i in range(3))
    u = pts[:, a] - pts[:, b]
    v = pts[:, c] - pts[:, b]
    norms = np.linalg.norm(u, axis=-1) * np.linalg.norm(v, axis=-1)
    with np.errstate(invalid="ignore", divide="ignore"):
        cos = np.sum(u * v, axis=-1) / norms
    cos = np.where(norms > 0, np.clip(cos, -1.0, 1.0), np.nan)
    return np.degrees(np.arccos(cos))
