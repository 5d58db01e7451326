"""A BVH skeleton as JSON-able ``motion`` group attrs, and back.

The attrs keep everything export needs to rebuild the file's layout: joint names and parents
(the contract's ``skeleton``), plus ``offsets`` and ``end_sites`` in metres, each joint's
``channels`` in file order and ``euler_orders`` (scipy intrinsic notation, one per joint; axes a
joint has no channel for are appended in X, Y, Z order), ``source_units`` and
``metres_per_unit`` of the file. One store holds one skeleton; :func:`skeleton_mismatch` says how
two differ.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from dancedata.io.bvh import BvhSkeleton

__all__ = ["SKELETON_KIND", "is_bvh_skeleton", "skeleton_attrs", "skeleton_from_attrs",
           "skeleton_mismatch"]  # fmt: skip

SKELETON_KIND = "bvh"


def skeleton_attrs(
    skeleton: BvhSkeleton, name: str, source_units: str, metres_per_unit: float
) -> dict[str, Any]:
    """The ``skeleton`` attrs of a skeleton whose lengths are already in metres."""
    return {
        "name": name,
        "kind": SKELETON_KIND,
        "joints": list(skeleton.names),
        "parents": list(skeleton.parents),
        "offsets": skeleton.offsets.tolist(),
        "channels": [list(c) for c in skeleton.channels],
        "euler_orders": list(skeleton.rotation_orders),
        "end_sites": [e.tolist() for e in skeleton.end_sites],
        "units": "m",
        "source_units": source_units,
        "metres_per_unit": float(metres_per_unit),
    }


def is_bvh_skeleton(attrs: dict[str, Any] | None) -> bool:
    """The skeleton attrs carry a BVH channel layout."""
    if not attrs:
        return False
    return attrs.get("kind") == SKELETON_KIND and "channels" in attrs


def skeleton_from_attrs(attrs: dict[str, Any]) -> BvhSkeleton:
    """The skeleton (lengths in metres) described by :func:`skeleton_attrs`."""
    n = len(attrs["joints"])
    ends = attrs.get("end_sites") or [[] for _ in range(n)]
    return BvhSkeleton(
        names=tuple(attrs["joints"]),
        parents=tuple(attrs["parents"]),
        offsets=np.asarray(attrs["offsets"], dtype=np.float64).reshape(n, 3),
        channels=tuple(tuple(c) for c in attrs["channels"]),
        end_sites=tuple(np.asarray(e, dtype=np.float64).reshape(-1, 3) for e in ends),
    )


def skeleton_mismatch(expected: BvhSkeleton, found: BvhSkeleton, atol_m: float) -> str | None:
    """None when the skeletons agree, else the first difference in words.

    Agree means: names, parents, channel lists and End Site counts exactly; End Sites within
    ``atol_m`` metres; and each OFFSET within ``atol_m`` on the components the joint's channels
    leave fixed. A position channel overwrites its OFFSET component in every frame, so that
    component says nothing about the rig (files of one rig with position channels on every
    joint, as in the Bandai-Namco set, write each take's first pose there)."""
    if expected.n_joints != found.n_joints:
        return f"{found.n_joints} joints, the store's skeleton has {expected.n_joints}"
    for j in range(expected.n_joints):
        name = expected.names[j]
        if found.names[j] != name:
            return f"joint {j} is {found.names[j]!r}, the store's is {name!r}"
        if found.parents[j] != expected.parents[j]:
            return f"joint {name!r} has another parent"
        if found.channels[j] != expected.channels[j]:
            return (
                f"joint {name!r} has channels {' '.join(found.channels[j])}, the store's "
                f"{' '.join(expected.channels[j])}"
            )
        fixed = expected._position_columns[j] < 0  # components no position channel overwrites
        if fixed.any():
            diff = float(np.abs(found.offsets[j] - expected.offsets[j])[fixed].max())
            if diff > atol_m:
                axes = "".join(a for a, f in zip("XYZ", fixed, strict=True) if f)
                return (
                    f"joint {name!r} OFFSET differs by {diff * 100:.3g} cm on its fixed "
                    f"component(s) {axes} (no position channel overwrites them)"
                )
        ends_a, ends_b = expected.end_sites[j], found.end_sites[j]
        if ends_a.shape != ends_b.shape:
            return f"joint {name!r} has {len(ends_b)} End Sites, the store's {len(ends_a)}"
        if ends_a.size and float(np.abs(ends_a - ends_b).max()) > atol_m:
            return f"joint {name!r} End Site differs by more than {atol_m * 100:.3g} cm"
    return None
