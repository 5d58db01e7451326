"""FID_k and FID_g (docs/METRICS.md, "FID"): Fréchet distances on the AIST++ kinetic (72-d) and
geometric (32-d) features of SMPL-24 joint positions (metres, y up).

The features are :func:`dancedata.compute.motion_features.kinetic_features` and
:func:`~dancedata.compute.motion_features.geometric_features`, bit-identical to the AIST++ API
(``mode="parity"`` keeps its acceleration precedence slip; ``frame_time_s`` = 1/120 s its
hard-coded velocity step). One feature vector per unit (sequence or measure: the caller
chooses the unit and records it).

The origin of the positions is a convention (:data:`ORIGINS`), because the reference kinetic
features are not translation invariant: with the AIST++ API's precedence slip the energy column
of each joint is about 3540 × its distance from the world origin. ``"world"`` (mint, the AIST++
API; default) keeps the positions as given; ``"first_frame_root"`` (Bailando
``calc_and_save_feats``) subtracts the unit's first-frame root joint from every joint and frame.
The geometric features are translation invariant, so FID_g is the same under both.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any, Literal

import numpy as np

from dancedata.compute.motion_features import geometric_features, kinetic_features
from dancedata.metrics.frechet import frechet_distance
from dancedata.metrics.result import MetricResult

__all__ = ["ORIGINS", "FeatureKind", "Origin", "fid", "motion_feature_matrix", "with_origin"]

FeatureKind = Literal["kinetic", "geometric"]
Origin = Literal["world", "first_frame_root"]
ORIGINS: tuple[str, ...] = ("world", "first_frame_root")
_NAMES = {"kinetic": "fid_k", "geometric": "fid_g"}


def with_origin(positions: np.ndarray, origin: Origin) -> np.ndarray:
    """(F, J, 3) positions placed by the origin convention: unchanged (``"world"``) or minus
    the first frame's joint 0 (``"first_frame_root"``)."""
    p = np.asarray(positions, dtype=np.float64)
    if origin == "world":
        return p
    if origin == "first_frame_root":
        return p - p[:1, :1, :]
    raise ValueError(f"origin must be one of {', '.join(ORIGINS)}, got {origin!r}")


def motion_feature_matrix(
    positions: Sequence[np.ndarray],
    kind: FeatureKind,
    *,
    fps: float = 60.0,
    kinetic_mode: Literal["parity", "corrected"] = "parity",
    geometric_frame_time_s: float = 1.0 / 120.0,
    origin: Origin = "world",
) -> np.ndarray:
    """(n_units, 72) kinetic or (n_units, 32) geometric features, one row per (F, 24, 3) unit,
    each unit placed by ``origin`` first (:func:`with_origin`)."""
    rows = []
    for p in positions:
        p = with_origin(p, origin)
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
    origin: Origin = "world",
    normalize: bool = True,
    drop_constant_ref_columns: bool = False,
    eps: float = 1e-6,
) -> MetricResult:
    """FID_k (``kind="kinetic"``) or FID_g (``"geometric"``) between two sets of units' joint
    positions; the reference set's statistics normalise (mint). Convention: the feature
    parameters plus those of :func:`~dancedata.metrics.frechet.frechet_distance`."""
    feats = {
        "fps": fps,
        "kinetic_mode": kinetic_mode,
        "geometric_frame_time_s": geometric_frame_time_s,
        "origin": origin,
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
    convention["origin"] = origin
    return MetricResult(
        result.name, result.value, convention, result.n_units, result.n_frames, result.details
    )
