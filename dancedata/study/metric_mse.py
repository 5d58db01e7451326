"""``mse``: reconstruction MSE of generated against ground-truth rows (docs/METRICS.md, "MSE").

Needs the rows of both sides in the MSE space (rotations); its unit is each sequence's shared
frames, or each complete measure (``mse_reduce = "measure_mean"``, needs the measures table).
The maths is :func:`dancedata.metrics.mse.mse`.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

from dancedata.errors import InputError
from dancedata.featurize.family_settings import setting
from dancedata.study.metric_registry import (
    Metric,
    MetricInputs,
    check_choices,
    register_metric,
)

if TYPE_CHECKING:
    from dancedata.metrics.result import MetricResult


@dataclass(frozen=True)
class MseSettings:
    """The MSE's space, angle wrapping and reduction (docs/METRICS.md, "MSE")."""

    mse_space: str = setting("euler75", help="MSE space: euler75, euler72 or rotmat.")
    mse_wrap: bool = setting(False, help="Wrap Euler angle differences to (−π, π] in the MSE.")
    mse_reduce: str = setting(
        "pooled",
        help="MSE reduction: pooled or sequence_mean (units: sequences), or measure_mean "
        "(units: the complete measures of the measures table).",
    )

    def __post_init__(self) -> None:
        check_choices(
            self,
            {
                "mse_space": ("euler75", "euler72", "rotmat"),
                "mse_reduce": ("pooled", "sequence_mean", "measure_mean"),
            },
        )
        if self.mse_wrap and self.mse_space == "rotmat":
            raise InputError("mse_wrap applies to Euler spaces only, not to rotmat")


def units(seqs: list, attr: str, by_measure: bool) -> list:
    """Each sequence's array ``attr`` whole, or cut into its complete measures."""
    if not by_measure:
        return [getattr(s, attr) for s in seqs]
    return [getattr(s, attr)[a:b] for s in seqs for a, b in s.measures]


@register_metric("mse")
class MseMetric(Metric):
    outputs = ("mse",)
    needs = ("rows", "measures")  # measures only for mse_reduce = measure_mean
    settings_type = MseSettings
    rank = 10
    experiment_outputs = ("mse",)

    def compute(self, inputs: MetricInputs, settings: MseSettings) -> list[MetricResult]:
        from dancedata.metrics.mse import mse

        by_measure = settings.mse_reduce == "measure_mean"
        rows = inputs.usable(self.outputs, "rows")
        if by_measure:
            rows = inputs.usable(self.outputs, "measures", rows)
        if not rows:
            return inputs.skip(self.outputs, "no sequence with rotations on both sides")

        def run() -> list[MetricResult]:
            result = mse(
                units(rows, "gt_rows", by_measure),
                units(rows, "gen_rows", by_measure),
                space=settings.mse_space,  # type: ignore[arg-type]
                wrap=settings.mse_wrap,
                reduce=settings.mse_reduce,  # type: ignore[arg-type]
                groups=[s.seq_id for s in rows],
            )
            result.convention["unit"] = "measure" if by_measure else "sequence"
            return [result]

        return inputs.guard(self.outputs, run)

    def score_reconstructions(self, cell: Any, names: list[str]) -> list[dict[str, Any]]:
        """MSE of the reconstruction over the measures (config ``mse_space``, ``mse_wrap``,
        ``mse_reduce``)."""
        from dancedata.metrics.mse import mse

        m = cell.metrics
        result = mse(
            cell.split(cell.truth75, "measure"),
            cell.split(cell.recon75, "measure"),
            space=m["mse_space"],
            wrap=m["mse_wrap"],
            reduce=m["mse_reduce"],
            groups=cell.groups(),
        )
        return [result.as_dict()]
