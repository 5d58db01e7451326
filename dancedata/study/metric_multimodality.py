"""``mm_k``, ``mm_g``: multimodality (docs/METRICS.md, "Multimodality"), several generations per
music piece (``evaluate --generations``): the mean over pieces of the mean pairwise feature
distance of that piece's generations, z-scored by the ground truth's features (as ``div_*``;
the feature settings are :class:`~dancedata.study.metric_features.FeatureSettings`).
The maths is :func:`dancedata.metrics.multimodality.multimodality`.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from typing import TYPE_CHECKING

from dancedata.study.metric_features import KINDS, FeatureSettings, feature_sequences
from dancedata.study.metric_mse import units
from dancedata.study.metric_registry import (
    EvalSequence,
    Metric,
    MetricInputs,
    register_metric,
)

if TYPE_CHECKING:
    import numpy as np

    from dancedata.metrics.result import MetricResult


def _multimodality(
    generations: Mapping[str, Sequence[np.ndarray]],
    seqs: list[EvalSequence],
    fps: float,
    p: FeatureSettings,
    reference: Sequence[np.ndarray] | None,
    kind: str,
) -> list[MetricResult]:
    """mm_k / mm_g: each group's generations (whole compared frames, one feature vector each),
    z-scored by the ground-truth units' features, as div_* is."""
    from dancedata.metrics.fid import motion_feature_matrix
    from dancedata.metrics.multimodality import multimodality
    from dancedata.metrics.result import MetricResult

    feats = p.feature_options(fps)
    gt = list(reference) if reference is not None else units(seqs, "gt_positions", False)
    ref = motion_feature_matrix(gt, kind, **feats) if p.normalize else None  # type: ignore[arg-type]
    groups = {k: motion_feature_matrix(list(v), kind, **feats) for k, v in generations.items()}  # type: ignore[arg-type]
    if p.drop_constant_ref_columns and ref is not None:  # as for FID and diversity
        keep = ref.std(axis=0) > 0
        ref, groups = ref[:, keep], {k: g[:, keep] for k, g in groups.items()}
    name = f"mm_{kind[0]}"
    frames = sum(len(a) for v in generations.values() for a in v)
    r = multimodality(groups, ref, name=name, n_frames=frames)
    if not r.details["n_groups"]:
        raise ValueError("no music piece has 2 or more generations")
    convention = {
        **r.convention,
        "features": kind,
        "group": "music",
        "drop_constant_ref_columns": p.drop_constant_ref_columns,
        **feats,
    }
    return [MetricResult(name, r.value, convention, r.n_units, r.n_frames, r.details)]


@register_metric("multimodality")
class MultimodalityMetrics(Metric):
    outputs = ("mm_k", "mm_g")
    needs = ("generations", "positions", "reference")
    settings_type = FeatureSettings
    rank = 60

    def compute(self, inputs: MetricInputs, settings: FeatureSettings) -> list[MetricResult]:
        generations = inputs.generations
        if generations is None:
            why = "needs several generations per music piece (evaluate --generations)"
            return inputs.skip(self.outputs, why)
        positions = feature_sequences(inputs, settings)  # the feature metrics' sequences
        out: list[MetricResult] = []
        for kind in KINDS:
            out += inputs.guard(
                [f"mm_{kind[0]}"],
                lambda kind=kind: _multimodality(
                    generations,
                    positions,
                    inputs.params.fps,
                    settings,
                    inputs.reference_positions,
                    kind,
                ),
            )
        return out
