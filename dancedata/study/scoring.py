"""Score generated motion against ground truth, sequence by sequence and as sets (pure).

Input: one :class:`EvalSequence` per sequence of the split, already cropped to the frames both
sides share, holding whatever each side offers (joint positions, axis-angle, MSE rows, music
beats). Output: one :class:`~dancedata.metrics.MetricResult` per metric, plus, for
every metric, the sequences it could not use and why: a sequence is never silently left out of a
mean. Every convention (docs/METRICS.md) that affects a number is a field of
:class:`EvaluateParams` and is recorded in each result's convention.

Every metric is registered (:mod:`dancedata.study.metric_registry`, one
``metric_<name>.py`` module each) with what it needs, its settings and its ``compute``;
:func:`evaluate_sequences` runs them all in order. The built-in ones and what they need (both
sides):

* ``mse``: MSE rows (rotations); unit = the sequence's shared frames, or each complete measure
  (``mse_reduce = "measure_mean"``).
* ``fid_k``, ``fid_g``, ``div_k``, ``div_g``, ``div_k_gt``, ``div_g_gt``: SMPL-24 positions;
  one feature vector per sequence (``fid_unit = "sequence"``) or per complete measure
  (``"measure"``), reference = the ground truth of the same units
  (``fid_reference = "paired_gt"``) or given reference units (``train_gt``, ``all_gt``); at
  least 2 units.
* ``bas_mint``, ``bas_bailando``, ``bas_msd_motion2music``, ``bas_msd_music2motion``,
  ``beat_coverage``, ``beat_hit_rate``, ``beat_accuracy``: generated positions + the music
  beats; per-sequence values averaged over sequences.
* ``fpd``, ``fmd``: axis-angle poses; per music piece, then the mean over pieces
  (``fpd_aggregate = "per_piece_mean"``) or one pooled distance.
* ``pfc``, ``pfc_gt``: EDGE's Physical Foot Contact score of the generated / ground-truth
  SMPL-24 positions, taken every ``fps / pfc_fps``-th frame (EDGE: 30 fps), whole sequences or
  clips of ``pfc_clip_frames`` frames at that rate; mean over clips × 10⁴.
* ``mm_k``, ``mm_g``: multimodality, several generations per music piece (``generations``):
  the mean over pieces of the mean pairwise feature distance of that piece's generations,
  z-scored by the ground truth's features (as ``div_*``).
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import FrozenInstanceError, asdict, dataclass, fields
from typing import Any

import numpy as np

from dancedata.errors import InputError
from dancedata.metrics import MetricResult
from dancedata.study.metric_registry import (
    EvalSequence,
    MetricInputs,
    ScoringSettings,
    metric_names,
    registered_metrics,
    settings_types,
)

__all__ = ["EvalSequence", "EvaluateParams", "Evaluation", "evaluate_sequences"]


class EvaluateParams:
    """Every convention choice of the evaluation (docs/METRICS.md); recorded per result.

    One flat set of fields: those of :class:`ScoringSettings` and of every registered metric's
    settings dataclass, each validated by its own class (``EvaluateParams(fid_unit="measure")``,
    ``params.fid_unit``, ``params.as_dict()``). ``settings(cls)`` is the part of one class, as a
    metric's ``compute`` receives it.
    """

    __slots__ = ("_parts",)

    def __init__(self, **values: Any) -> None:
        parts: dict[type, Any] = {}
        for cls in settings_types():
            names = [f.name for f in fields(cls)]
            parts[cls] = cls(**{k: values.pop(k) for k in names if k in values})
        if values:
            raise TypeError(f"EvaluateParams got unknown field(s) {sorted(values)}")
        scoring = parts[ScoringSettings]
        for part in parts.values():
            check = getattr(part, "check", None)
            if check is not None:
                check(scoring)
        object.__setattr__(self, "_parts", parts)

    def __getattr__(self, name: str) -> Any:
        for part in object.__getattribute__(self, "_parts").values():
            if name in part.__dataclass_fields__:
                return getattr(part, name)
        raise AttributeError(f"EvaluateParams has no field {name!r}")

    def __setattr__(self, name: str, value: Any) -> None:
        raise FrozenInstanceError(f"cannot assign to field {name!r}")

    def __eq__(self, other: object) -> bool:
        return isinstance(other, EvaluateParams) and self.as_dict() == other.as_dict()

    def __hash__(self) -> int:
        return hash(tuple(self._parts.values()))

    def __repr__(self) -> str:
        inner = ", ".join(f"{k}={v!r}" for k, v in self.as_dict().items())
        return f"EvaluateParams({inner})"

    def settings(self, cls: type | None) -> Any:
        """The settings instance of ``cls`` (None for a metric without settings)."""
        return None if cls is None else self._parts[cls]

    def as_dict(self) -> dict[str, Any]:
        return {k: v for part in self._parts.values() for k, v in asdict(part).items()}


@dataclass
class Evaluation:
    """Results and, per metric, the sequences left out with their reasons."""

    results: list[MetricResult]
    unscored: dict[str, list[dict[str, str]]]  # metric -> [{seq_id, reason}]
    skipped_metrics: dict[str, str]  # metric -> reason no value exists


def _with_unscored(result: MetricResult, params: EvaluateParams) -> MetricResult:
    convention = {
        **result.convention,
        "skip_frames": params.skip_frames,
        "max_frames": params.max_frames,
        "length": params.length,
    }
    return MetricResult(
        result.name, result.value, convention, result.n_units, result.n_frames, result.details
    )


def evaluate_sequences(
    seqs: Sequence[EvalSequence],
    params: EvaluateParams,
    unreadable: Sequence[dict[str, str]] = (),
    reference_positions: Sequence[np.ndarray] | None = None,
    generations: Mapping[str, Sequence[np.ndarray]] | None = None,
) -> Evaluation:
    """Every registered metric over ``seqs``; ``unreadable`` ({seq_id, reason}) are
    sequences with no usable generated motion at all, listed as unscored under every metric.
    ``reference_positions``: the FID / diversity reference units when ``fid_reference`` is not
    ``paired_gt`` (e.g. every train sequence's ground truth, cut as ``fid_unit`` says).
    ``generations``: music piece → the SMPL-24 positions of its several generations (mm_k,
    mm_g); skipped when None."""
    if (params.fid_reference == "paired_gt") != (reference_positions is None):
        raise InputError(
            f"fid_reference {params.fid_reference!r} "
            + ("takes no" if reference_positions is not None else "needs")
            + " reference positions"
        )
    names = metric_names()
    inputs = MetricInputs(seqs, params, reference_positions, generations)
    inputs.unscored.update({name: [] for name in names})
    for item in unreadable:
        for name in names:
            inputs.unscored[name].append(dict(item))
    out: list[MetricResult] = []
    for metric in registered_metrics().values():
        settings = params.settings(metric.settings_type)
        results = inputs.guard(metric.outputs, lambda m=metric, s=settings: m.compute(inputs, s))
        stray = sorted({r.name for r in results} - set(metric.outputs))
        if stray:
            raise TypeError(f"metric {metric.name!r} returned {stray}, not among its outputs")
        out += results
    out.sort(key=lambda r: names.index(r.name))
    results = [_with_unscored(r, params) for r in out]
    return Evaluation(results, inputs.unscored, inputs.skipped)
