"""``pfc``, ``pfc_gt``: EDGE's Physical Foot Contact score (docs/METRICS.md, "PFC") of the
generated / ground-truth SMPL-24 positions, taken every ``fps / pfc_fps``-th frame (EDGE: 30
fps), whole sequences or clips of ``pfc_clip_frames`` frames at that rate; mean over clips ×
10⁴. The maths is :func:`dancedata.metrics.pfc.pfc`.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

from dancedata.errors import InputError
from dancedata.featurize.family_settings import setting
from dancedata.study.metric_registry import (
    EvalSequence,
    Metric,
    MetricInputs,
    ScoringSettings,
    register_metric,
)

if TYPE_CHECKING:
    from dancedata.metrics.result import MetricResult


@dataclass(frozen=True)
class PfcSettings:
    """The frame rate PFC is computed at and its clip length."""

    pfc_fps: float = setting(
        30.0,
        help="Frame rate PFC is computed at (EDGE: 30; every fps/pfc_fps-th frame). PFC "
        "uses per-frame foot displacements, so it changes with this rate.",
    )
    pfc_clip_frames: int | None = setting(
        None,
        help="PFC clip length in frames at --pfc-fps (EDGE's 5-s clips: 150); default: "
        "each scored sequence is one clip.",
        min=3,
    )

    def __post_init__(self) -> None:
        if self.pfc_clip_frames is not None and self.pfc_clip_frames < 3:
            raise InputError(f"pfc_clip_frames must be at least 3, got {self.pfc_clip_frames}")

    def check(self, scoring: ScoringSettings) -> None:
        scoring.frame_step("pfc_fps", self.pfc_fps)


def _pfc(seqs: list[EvalSequence], fps: float, p: PfcSettings, side: str) -> list[MetricResult]:
    """PFC of one side ("gen" or "gt") at ``pfc_fps``: positions are y up here, which gives
    EDGE's z-up value (a rotation keeps the horizontal plane and the up clamp)."""
    from dancedata.metrics.pfc import pfc
    from dancedata.metrics.result import MetricResult

    step = round(fps / p.pfc_fps)
    name = "pfc" if side == "gen" else "pfc_gt"
    positions = [getattr(s, f"{side}_positions")[::step] for s in seqs]
    result = pfc(positions, fps=p.pfc_fps, up_axis="y", clip_frames=p.pfc_clip_frames, name=name)
    if not result.n_units:
        raise ValueError("no clip with root acceleration (PFC undefined everywhere)")
    convention = {**result.convention, "source_fps": fps, "frame_step": step}
    return [
        MetricResult(
            name, result.value, convention, result.n_units, result.n_frames, result.details
        )
    ]


@register_metric("pfc")
class PfcMetrics(Metric):
    outputs = ("pfc", "pfc_gt")
    needs = ("gen_positions", "gt_positions")  # pfc: generated, pfc_gt: ground truth
    settings_type = PfcSettings
    rank = 50
    experiment_outputs = ("pfc",)

    def compute(self, inputs: MetricInputs, settings: PfcSettings) -> list[MetricResult]:
        out: list[MetricResult] = []
        for side, name in (("gen", "pfc"), ("gt", "pfc_gt")):
            usable = inputs.usable([name], f"{side}_positions")
            if not usable:
                inputs.skip([name], "no sequence with SMPL-24 joint positions")
                continue
            out += inputs.guard(
                [name], lambda u=usable, side=side: _pfc(u, inputs.params.fps, settings, side)
            )
        return out

    def score_reconstructions(self, cell: Any, names: list[str]) -> list[dict[str, Any]]:
        """PFC of the reconstruction's positions, one sequence (or ``pfc_clip_frames`` clip)
        per unit, every ``fps / pfc_fps``-th frame (config ``pfc_clip_frames`` 0: whole)."""
        from dancedata.metrics.pfc import pfc

        m = cell.metrics
        step = round(cell.fps / float(m["pfc_fps"]))
        units = [u[::step] for u in cell.split(cell.positions("gen"), "sequence")]
        clip = int(m["pfc_clip_frames"]) or None
        record = pfc(units, fps=float(m["pfc_fps"]), up_axis="y", clip_frames=clip).as_dict()
        record["convention"].update(
            source_fps=cell.fps,
            frame_step=step,
            unit="sequence",
            positions="SMPL-24 FK (metres, y up)",
            skeleton=cell.skeleton.name,
        )
        return [record]
