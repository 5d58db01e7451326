"""FID_k and FID_g (EXPERIMENTS.md §4.2): Fréchet distances on the AIST++ kinetic (72-d) and
geometric (32-d) features of SMPL-24 joint positions (metres, y up).

The features are :func:`dancedata.compute.motion_features.kinetic_features` and
:func:`~dancedata.compute.motion_features.geometric_features`, bit-identical to the AIST++ API
(``mode="parity"`` keeps its acceleration precedence slip; ``frame_time_s`` = 1/120 s its
hard-coded velocity step). One feature vector per unit (sequence or measure: the caller
chooses the unit and records it).
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any, Literal

import numpy as np

from dancedata.compute.motion_features import geometric_features, kinetic_features
from dancedata.experiments.metrics.frechet import frechet_distance
from dancedata.experiments.metrics.result import MetricResult

__all__ = ["FeatureKind", "fid", "motion_feature_matrix"]

FeatureKind = Literal["kinetic", "geometric"]
_NAMES = {"kinetic": "fid_k", "geometric": "fid_g"}


def motion_feature_matrix(
    positions: Sequence[np.ndarray],
    kind: FeatureKind,
    *,
    fps: float = 60.0,
    kinetic_mode: Literal["parity", "corrected"] = "parity",
    geometric_frame_time_s: float = 1.0 / 120.0,
    root_relative_first_frame: bool = False,
) -> np.ndarray:
    """(n_units, 72) kinetic or (n_units, 32) geometric features, one row per (F, 24, 3) unit.

    ``root_relative_first_frame`` subtracts the first frame's root from every joint of the unit
    (Bailando ``calc_and_save_feats``; off in mint).
    """
    rows = []
    for p in positions:
        p = np.asarray(p, dtype=np.float64)
        if root_relative_first_frame:
            p = p - p[:1, :1, :]
        if kind == "kinetic":
            rows.append(kinetic_features(p, fps, mode=kinetic_mode, up_axis="y"))
        elif kind == "geometric":
            rows.append(geometric_features(p, geometric_frame_time_s))
        else:
            raise ValueError(f"feature kind must be kinetic or geometric, got {kind!r}")
    width = 72 if kind == "kinetic" else 32
    return np.stack(rows) if rows else np.zeros((0, width))


def fid(
    evaluated_positions: Sequence[np.ndarray],
    reference_positions: Sequence[np.ndarray],
    kind: FeatureKind,
    *,
    fps: float = 60.0,
    kinetic_mode: Literal["parity", "corrected"] = "parity",
    geometric_frame_time_s: float = 1.0 / 120.0,
    root_relative_first_frame: bool = False,
    normalize: bool = True,
    drop_constant_ref_columns: bool = False,
    eps: float = 1e-6,
) -> MetricResult:
    """FID_k (``kind="kinetic"``) or FID_g (``"geometric"``) between two sets of units' joint
    positions; the reference set's statistics normalise (mint). Convention: the feature
    parameters plus those of :func:`~dancedata.experiments.metrics.frechet.frechet_distance`."""
    feats = {
        "fps": fps,
        "kinetic_mode": kinetic_mode,
        "geometric_frame_time_s": geometric_frame_time_s,
        "root_relative_first_frame": root_relative_first_frame,
    }
    evaluated = motion_feature_matrix(evaluated_positions, kind, **feats)
    reference = motion_feature_matrix(reference_positions, kind, **feats)
    result = frechet_distance(
        evaluated,
        reference,
        name=_NAMES[kind],
        normalize=normalize,
        drop_constant_ref_columns=drop_constant_ref_columns,
        eps=eps,
        n_frames=sum(int(np.shape(p)[0]) for p in evaluated_positions),
    )
    convention: dict[str, Any] = {"features": kind, **result.convention}
    if kind == "kinetic":
        convention.update(fps=fps, kinetic_mode=kinetic_mode)
    else:
        convention.update(geometric_frame_time_s=geometric_frame_time_s)
    convention["root_relative_first_frame"] = root_relative_first_frame
    return MetricResult(
        result.name, result.value, convention, result.n_units, result.n_frames, result.details
    )
