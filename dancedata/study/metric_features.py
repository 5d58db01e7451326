"""``fid_k``, ``fid_g``, ``div_k``, ``div_g``, ``div_k_gt``, ``div_g_gt``: Fréchet distances and
diversity on the AIST++ kinetic and geometric features (docs/METRICS.md, "FID", "Diversity").

Needs SMPL-24 positions of both sides; one feature vector per sequence (``fid_unit =
"sequence"``) or per complete measure (``"measure"``), reference = the ground truth of the same
units (``fid_reference = "paired_gt"``) or given reference units (``train_gt``, ``all_gt``); at
least 2 units. :class:`FeatureSettings` is shared with multimodality (``mm_k``, ``mm_g``). The
maths is :mod:`dancedata.metrics.fid` and ``.diversity``.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

from dancedata.errors import InputError
from dancedata.featurize.family_settings import setting
from dancedata.study.metric_mse import units
from dancedata.study.metric_registry import (
    EvalSequence,
    Metric,
    MetricInputs,
    check_choices,
    register_metric,
)

if TYPE_CHECKING:
    import numpy as np

    from dancedata.metrics.result import MetricResult

KINDS = ("kinetic", "geometric")


@dataclass(frozen=True)
class FeatureSettings:
    """How the motion features of FID, diversity and multimodality are made and compared."""

    fid_unit: str = setting(
        "sequence",
        help="FID / diversity unit: sequence (one feature vector each) or measure (each "
        "complete measure of the measures table).",
    )
    fid_reference: str = setting(
        "paired_gt",
        help="FID / diversity reference: paired_gt (the ground truth of the scored units), "
        "train_gt (the train split) or all_gt (every sequence, as mint's all of AIST++).",
    )
    kinetic_mode: str = setting(
        "parity", help="Kinetic features: parity (AIST++ code) or corrected."
    )
    geometric_frame_time_s: float = 1.0 / 120.0
    normalize: bool = setting(
        True, help="z-score FID / diversity features by the ground truth's stats."
    )
    drop_constant_ref_columns: bool = setting(
        False, help="Drop feature columns constant in the ground truth (FID)."
    )
    fid_eps: float = setting(1e-6, help="ε added to covariances when sqrtm is not finite.")
    fid_origin: str = setting(
        "world",
        help="Origin of the positions before the FID / diversity features: world (mint, "
        "AIST++ API) or first_frame_root (Bailando: each unit minus its first-frame root). "
        "Changes FID_k, not FID_g (docs/METRICS.md).",
    )
    # FID / diversity on each sequence's first N compared frames only (Bailando: 1200), while
    # the beat scores and MSE use every compared frame; None: no extra cut.
    feature_max_frames: int | None = setting(
        None,
        help="FID / diversity on each sequence's first N compared frames only; beat scores "
        "and MSE keep every frame (Bailando: 1200).",
        min=3,
    )

    def __post_init__(self) -> None:
        check_choices(
            self,
            {
                "fid_unit": ("sequence", "measure"),
                "fid_reference": ("paired_gt", "train_gt", "all_gt"),
                "kinetic_mode": ("parity", "corrected"),
                "fid_origin": ("world", "first_frame_root"),
            },
        )
        if self.feature_max_frames is not None and (
            self.feature_max_frames < 3 or self.fid_unit != "sequence"
        ):
            raise InputError("feature_max_frames must be at least 3 and needs fid_unit sequence")

    def feature_options(self, fps: float) -> dict[str, Any]:
        """The keyword arguments of ``motion_feature_matrix`` (and the convention they make)."""
        return {
            "fps": fps,
            "kinetic_mode": self.kinetic_mode,
            "geometric_frame_time_s": self.geometric_frame_time_s,
            "origin": self.fid_origin,
        }


def _feature_metrics(
    seqs: list[EvalSequence],
    fps: float,
    p: FeatureSettings,
    reference: Sequence[np.ndarray] | None,
    kind: str,
) -> list[MetricResult]:
    from dancedata.metrics.diversity import diversity
    from dancedata.metrics.fid import fid, motion_feature_matrix
    from dancedata.metrics.result import MetricResult

    by_measure = p.fid_unit == "measure"
    gen = units(seqs, "gen_positions", by_measure)
    gt = list(reference) if reference is not None else units(seqs, "gt_positions", by_measure)
    if p.feature_max_frames is not None:  # Bailando: the first 1200 frames of each sequence
        gen = [u[: p.feature_max_frames] for u in gen]
        if reference is None:  # paired ground truth: the same frames; a reference set stays whole
            gt = [u[: p.feature_max_frames] for u in gt]
    frames = sum(len(u) for u in gen)
    unit: dict[str, Any] = {"unit": p.fid_unit, "reference": p.fid_reference}
    if p.feature_max_frames is not None:
        unit["feature_max_frames"] = p.feature_max_frames
    out = []
    suffix = kind[0]
    result = fid(
        gen,
        gt,
        kind,  # type: ignore[arg-type]
        fps=fps,
        kinetic_mode=p.kinetic_mode,  # type: ignore[arg-type]
        geometric_frame_time_s=p.geometric_frame_time_s,
        origin=p.fid_origin,  # type: ignore[arg-type]
        normalize=p.normalize,
        drop_constant_ref_columns=p.drop_constant_ref_columns,
        eps=p.fid_eps,
    )
    out.append(
        MetricResult(
            result.name,
            result.value,
            {**result.convention, **unit},
            result.n_units,
            result.n_frames,
            result.details,
        )
    )
    feats = p.feature_options(fps)
    f_gen = motion_feature_matrix(gen, kind, **feats)  # type: ignore[arg-type]
    f_gt = motion_feature_matrix(gt, kind, **feats)  # type: ignore[arg-type]
    if p.drop_constant_ref_columns:
        keep = f_gt.std(axis=0) > 0
        f_gen, f_gt = f_gen[:, keep], f_gt[:, keep]
    ref = f_gt if p.normalize else None
    conv = {
        "features": kind,
        **unit,
        "drop_constant_ref_columns": p.drop_constant_ref_columns,
        "origin": p.fid_origin,
    }
    gt_frames = sum(len(u) for u in gt)
    for name, values, count in (
        (f"div_{suffix}", f_gen, frames),
        (f"div_{suffix}_gt", f_gt, gt_frames),
    ):
        r = diversity(values, ref, name=name, n_frames=count)
        out.append(MetricResult(name, r.value, {**r.convention, **conv}, r.n_units, r.n_frames))
    return out


def feature_sequences(inputs: MetricInputs, p: FeatureSettings, names: Sequence[str] = ()
                      ) -> list[EvalSequence]:  # fmt: skip
    """The sequences the feature metrics use: positions on both sides (and complete measures
    for ``fid_unit = "measure"``); the others are unscored under ``names``."""
    positions = inputs.usable(names, "positions")
    if p.fid_unit == "measure":
        positions = inputs.usable(names, "measures", positions)
    return positions


@register_metric("features")
class FeatureMetrics(Metric):
    outputs = ("fid_k", "fid_g", "div_k", "div_g", "div_k_gt", "div_g_gt")
    needs = ("positions", "measures", "reference")  # measures for fid_unit = measure
    settings_type = FeatureSettings
    rank = 20
    experiment_outputs = ("fid_g", "fid_k")

    def compute(self, inputs: MetricInputs, settings: FeatureSettings) -> list[MetricResult]:
        positions = feature_sequences(inputs, settings, self.outputs)
        n_units = len(units(positions, "gt_positions", settings.fid_unit == "measure"))
        if n_units < 2:
            unit = settings.fid_unit
            why = f"needs joint positions of at least 2 units ({unit}s), have {n_units}"
            return inputs.skip(self.outputs, why)
        fps = inputs.params.fps
        out: list[MetricResult] = []
        for kind in KINDS:
            out += inputs.guard(
                [f"fid_{kind[0]}", f"div_{kind[0]}", f"div_{kind[0]}_gt"],
                lambda kind=kind: _feature_metrics(
                    positions, fps, settings, inputs.reference_positions, kind
                ),
            )
        return out

    def score_reconstructions(self, cell: Any, names: list[str]) -> list[dict[str, Any]]:
        """FID of the reconstruction's positions against the ground truth of the same frames
        (``fid_reference = paired_gt``), per sequence or per measure (config ``fid_unit``)."""
        from dancedata.metrics.fid import fid

        m = cell.metrics
        units = cell.n_units(m["fid_unit"])
        if units < 2:
            why = (
                f"FID needs ≥ 2 units, the split gives {units} "
                f"({m['fid_unit']}); try fid_unit = measure"
            )
            for name in names:
                cell.skip(name, why)
            return []
        fake = cell.split(cell.positions("gen"), m["fid_unit"])
        real = cell.split(cell.positions("gt"), m["fid_unit"])
        out = []
        for name in names:
            result = fid(
                fake,
                real,
                "kinetic" if name == "fid_k" else "geometric",
                fps=cell.fps,
                kinetic_mode=m["kinetic_mode"],
                geometric_frame_time_s=float(m["geometric_frame_time"]),
                normalize=m["normalize"],
                drop_constant_ref_columns=m["drop_constant_ref_columns"],
                origin=m["fid_origin"],
            )
            record = result.as_dict()
            record["convention"].update(
                unit=m["fid_unit"],
                reference=m["fid_reference"],
                positions="SMPL-24 FK (metres, y up)",
                skeleton=cell.skeleton.name,
            )
            out.append(record)
        return out
