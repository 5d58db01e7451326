"""``fpd``, ``fmd``: Fréchet pose and motion distances on axis-angle poses (docs/METRICS.md,
"FPD / FMD"; ChoreoGraph after Transflower), per music piece and then the mean over pieces
(``fpd_aggregate = "per_piece_mean"``) or one pooled distance. Needs the axis-angle poses of
both sides; no joint positions. The maths is :mod:`dancedata.metrics.fpd`.
"""

from __future__ import annotations

from collections import defaultdict
from dataclasses import dataclass
from typing import TYPE_CHECKING

from dancedata.errors import InputError
from dancedata.featurize.family_settings import setting
from dancedata.study.metric_registry import (
    EvalSequence,
    Metric,
    MetricInputs,
    check_choices,
    register_metric,
)

if TYPE_CHECKING:
    from dancedata.metrics.result import MetricResult


@dataclass(frozen=True)
class FpdSettings:
    """FPD / FMD's convention, aggregation over music pieces and frame step."""

    fpd_parity: str = setting(
        "spec", help="FPD/FMD convention: spec (covariance, sliding) or transflower."
    )
    fpd_aggregate: str = setting(
        "per_piece_mean", help="FPD/FMD over music pieces: per_piece_mean or pooled."
    )
    fpd_frame_step: int = 3

    def __post_init__(self) -> None:
        check_choices(
            self,
            {
                "fpd_parity": ("spec", "transflower"),
                "fpd_aggregate": ("per_piece_mean", "pooled"),
            },
        )
        if self.fpd_frame_step < 1:
            raise InputError("skip_frames and beat_tol must be ≥ 0, fpd_frame_step ≥ 1")


@register_metric("fpd")
class FpdMetrics(Metric):
    outputs = ("fpd", "fmd")
    needs = ("axis_angle",)
    settings_type = FpdSettings
    rank = 40

    def compute(self, inputs: MetricInputs, settings: FpdSettings) -> list[MetricResult]:
        poses = inputs.usable(self.outputs, "axis_angle")
        if not poses:
            return inputs.skip(self.outputs, "no sequence with rotations on both sides")
        return inputs.guard(self.outputs, lambda: _fpd_metrics(poses, settings))


def _fpd_metrics(seqs: list[EvalSequence], p: FpdSettings) -> list[MetricResult]:
    import numpy as np

    from dancedata.metrics.fpd import fmd, fpd
    from dancedata.metrics.result import MetricResult

    pieces: dict[str, list[EvalSequence]] = defaultdict(list)
    if p.fpd_aggregate == "pooled":
        pieces["all"] = list(seqs)
    else:
        for s in seqs:
            pieces[s.music_id or s.seq_id].append(s)
    out = []
    for name, function in (("fpd", fpd), ("fmd", fmd)):
        per_piece = [
            function(
                [s.gen_axis_angle for s in group],  # type: ignore[misc]
                [s.gt_axis_angle for s in group],  # type: ignore[misc]
                frame_step=p.fpd_frame_step,
                parity=p.fpd_parity,  # type: ignore[arg-type]
            )
            for group in pieces.values()
        ]
        convention = {
            **per_piece[0].convention,
            "aggregate": p.fpd_aggregate,
            "poses": "smpl24_axis_angle",
            "root_translation": False,
        }
        out.append(
            MetricResult(
                name,
                float(np.mean([r.value for r in per_piece])),
                convention,
                len(seqs),
                sum(s.n_frames for s in seqs),
                {
                    "n_pieces": len(per_piece),
                    "per_piece": {k: r.value for k, r in zip(pieces, per_piece, strict=True)},
                },
            )
        )
    return out
