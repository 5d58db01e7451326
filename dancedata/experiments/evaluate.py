"""Score generated motion against ground truth, sequence by sequence and as sets (pure).

Input: one :class:`EvalSequence` per sequence of the split, already cropped to the frames both
sides share, holding whatever each side offers (joint positions, axis-angle, MSE rows, music
beats). Output: one :class:`~dancedata.experiments.metrics.MetricResult` per metric, plus, for
every metric, the sequences it could not use and why: a sequence is never silently left out of a
mean. Every convention (docs/METRICS.md) that affects a number is a field of
:class:`EvaluateParams` and is recorded in each result's convention.

Metrics and what they need (both sides):

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

import math
from collections import defaultdict
from collections.abc import Callable, Mapping, Sequence
from dataclasses import asdict, dataclass, field
from typing import Any

import numpy as np

from dancedata.errors import InputError
from dancedata.experiments.metrics import (
    MetricResult,
    bas_bailando,
    bas_mint,
    bas_msd,
    beat_counts,
    diversity,
    fid,
    fmd,
    fpd,
    mean_over_units,
    motion_beats_choreograph,
    motion_feature_matrix,
    mse,
)
from dancedata.experiments.metrics.beats import decimate_beats
from dancedata.experiments.metrics.multimodality import multimodality
from dancedata.experiments.metrics.pfc import pfc

__all__ = ["METRICS", "EvalSequence", "EvaluateParams", "Evaluation", "evaluate_sequences"]

METRICS = (
    "mse",
    "fid_k",
    "fid_g",
    "div_k",
    "div_g",
    "div_k_gt",
    "div_g_gt",
    "bas_mint",
    "bas_bailando",
    "bas_msd_motion2music",
    "bas_msd_music2motion",
    "beat_coverage",
    "beat_hit_rate",
    "beat_accuracy",
    "fpd",
    "fmd",
    "pfc",
    "pfc_gt",
    "mm_k",
    "mm_g",
)
_FEATURE_METRICS = ("fid_k", "fid_g", "div_k", "div_g", "div_k_gt", "div_g_gt")
_BEAT_METRICS = METRICS[7:14]
_BEAT_SOURCES = {  # evaluate's beat_source -> the store array and its recipe, recorded
    "fact": "audio/beats (FACT: librosa beat_track, start_bpm = music BPM)",
    "bailando": "audio/beats_bailando (Bailando: HPSS percussive, median onset, beat_track)",
}


@dataclass(frozen=True)
class EvaluateParams:
    """Every convention choice of the evaluation (docs/METRICS.md); recorded per result."""

    fps: float = 60.0
    mse_space: str = "euler75"
    mse_wrap: bool = False
    mse_reduce: str = "pooled"
    euler_order: str = "XYZ"
    fid_unit: str = "sequence"
    fid_reference: str = "paired_gt"
    kinetic_mode: str = "parity"
    geometric_frame_time_s: float = 1.0 / 120.0
    normalize: bool = True
    drop_constant_ref_columns: bool = False
    fid_eps: float = 1e-6
    bas_sigma: float = 3.0
    mint_order: int = 10
    bailando_smoothing_sigma: float = 5.0
    msd_fps: float = 20.0
    beat_tol: int = 12
    beat_detector: str = "mint"
    fpd_parity: str = "spec"
    fpd_aggregate: str = "per_piece_mean"
    fpd_frame_step: int = 3
    skip_frames: int = 0
    max_frames: int | None = None
    length: str = "common_min"
    fid_origin: str = "world"
    # FID / diversity on each sequence's first N compared frames only (Bailando: 1200), while
    # the beat scores and MSE use every compared frame; None: no extra cut.
    feature_max_frames: int | None = None
    # The named preset the other fields were set from (``evaluate --convention``), or None.
    convention: str | None = None
    pfc_fps: float = 30.0
    bas_beats: str = "motion_span"
    beat_source: str = "fact"
    pfc_clip_frames: int | None = None

    def __post_init__(self) -> None:
        allowed = {
            "mse_space": ("euler75", "euler72", "rotmat"),
            "mse_reduce": ("pooled", "sequence_mean", "measure_mean"),
            "fid_unit": ("sequence", "measure"),
            "fid_reference": ("paired_gt", "train_gt", "all_gt"),
            "kinetic_mode": ("parity", "corrected"),
            "fid_origin": ("world", "first_frame_root"),
            "bas_beats": ("motion_span", "whole_track_mint"),
            "beat_source": ("fact", "bailando"),
            "beat_detector": ("mint", "bailando"),
            "fpd_parity": ("spec", "transflower"),
            "fpd_aggregate": ("per_piece_mean", "pooled"),
            "length": ("common_min",),
        }
        for name, options in allowed.items():
            if getattr(self, name) not in options:
                raise InputError(
                    f"{name} must be one of {', '.join(options)} for evaluate, "
                    f"got {getattr(self, name)!r}"
                )
        if self.mse_wrap and self.mse_space == "rotmat":
            raise InputError("mse_wrap applies to Euler spaces only, not to rotmat")
        if self.max_frames is not None and self.max_frames < 3:
            raise InputError(f"max_frames must be at least 3, got {self.max_frames}")
        if self.feature_max_frames is not None and (
            self.feature_max_frames < 3 or self.fid_unit != "sequence"
        ):
            raise InputError("feature_max_frames must be at least 3 and needs fid_unit sequence")
        if self.skip_frames < 0 or self.beat_tol < 0 or self.fpd_frame_step < 1:
            raise InputError("skip_frames and beat_tol must be ≥ 0, fpd_frame_step ≥ 1")
        step = self.fps / self.msd_fps if self.msd_fps > 0 else 0.0
        if step < 1 or abs(step - round(step)) > 1e-9:
            raise InputError(f"msd_fps {self.msd_fps} must divide fps {self.fps}")
        step = self.fps / self.pfc_fps if self.pfc_fps > 0 else 0.0
        if step < 1 or abs(step - round(step)) > 1e-9:
            raise InputError(f"pfc_fps {self.pfc_fps} must divide fps {self.fps}")
        if self.pfc_clip_frames is not None and self.pfc_clip_frames < 3:
            raise InputError(f"pfc_clip_frames must be at least 3, got {self.pfc_clip_frames}")

    def as_dict(self) -> dict[str, Any]:
        return asdict(self)


@dataclass(frozen=True)
class EvalSequence:
    """One sequence, ground truth and generated, cropped to the same frames.

    Attributes:
        seq_id, music_id: identifiers (music_id groups FPD/FMD per piece).
        n_frames: frames used (after ``skip_frames``, the shorter of the two).
        gt_positions, gen_positions: (F, 24, 3) SMPL joint positions, m, y up; or None.
        gt_rows, gen_rows: (F, D) rows in the MSE space; or None.
        gt_axis_angle, gen_axis_angle: (F, 24, 3) axis-angle, rad; or None.
        music_beats: music-beat frame indices in the used frames' time base; or None.
        measures: [start, stop) of every complete measure inside the used frames (the
            store's measures table, same time base); the units of ``fid_unit = "measure"``
            and ``mse_reduce = "measure_mean"``.
        music_beats_track: the music beats from the first used frame to the end of the track
            (same time base; beats past the last motion frame included), for ``bas_beats =
            "whole_track_mint"``; or None.
        gen_positions_before: the generated positions of the skipped first frames
            (``skip_frames``): ``bas_mint`` detects motion beats on the whole clip and drops
            the skipped frames afterwards, as mint does with its 120 seed frames.
        missing: why a side lacks something (e.g. ``{"positions": "no --smpl-model"}``).
    """

    seq_id: str
    music_id: str | None
    n_frames: int
    gt_positions: np.ndarray | None = None
    gen_positions: np.ndarray | None = None
    gt_rows: np.ndarray | None = None
    gen_rows: np.ndarray | None = None
    gt_axis_angle: np.ndarray | None = None
    gen_axis_angle: np.ndarray | None = None
    music_beats: np.ndarray | None = None
    measures: tuple[tuple[int, int], ...] = ()
    gen_positions_before: np.ndarray | None = None
    missing: dict[str, str] = field(default_factory=dict)
    music_beats_track: np.ndarray | None = None


@dataclass
class Evaluation:
    """Results and, per metric, the sequences left out with their reasons."""

    results: list[MetricResult]
    unscored: dict[str, list[dict[str, str]]]  # metric -> [{seq_id, reason}]
    skipped_metrics: dict[str, str]  # metric -> reason no value exists


def _needs(
    seqs: Sequence[EvalSequence],
    metric_names: Sequence[str],
    what: str,
    check: Callable[[EvalSequence], bool],
    unscored: dict[str, list[dict[str, str]]],
) -> list[EvalSequence]:
    usable = []
    for s in seqs:
        if check(s):
            usable.append(s)
            continue
        reason = s.missing.get(what, f"no {what}")
        for name in metric_names:
            unscored[name].append({"seq_id": s.seq_id, "reason": reason})
    return usable


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


def _units(seqs: list[EvalSequence], attr: str, by_measure: bool) -> list[np.ndarray]:
    """Each sequence's array whole, or cut into its complete measures."""
    if not by_measure:
        return [getattr(s, attr) for s in seqs]
    return [getattr(s, attr)[a:b] for s in seqs for a, b in s.measures]


def _feature_metrics(
    seqs: list[EvalSequence],
    p: EvaluateParams,
    out: list[MetricResult],
    reference: Sequence[np.ndarray] | None = None,
    kinds: tuple[str, ...] = ("kinetic", "geometric"),
) -> None:
    by_measure = p.fid_unit == "measure"
    gen = _units(seqs, "gen_positions", by_measure)
    gt = list(reference) if reference is not None else _units(seqs, "gt_positions", by_measure)
    if p.feature_max_frames is not None:  # Bailando: the first 1200 frames of each sequence
        gen = [u[: p.feature_max_frames] for u in gen]
        if reference is None:  # paired ground truth: the same frames; a reference set stays whole
            gt = [u[: p.feature_max_frames] for u in gt]
    frames = sum(len(u) for u in gen)
    unit: dict[str, Any] = {"unit": p.fid_unit, "reference": p.fid_reference}
    if p.feature_max_frames is not None:
        unit["feature_max_frames"] = p.feature_max_frames
    for kind in kinds:
        suffix = kind[0]
        result = fid(
            gen,  # type: ignore[arg-type]
            gt,  # type: ignore[arg-type]
            kind,  # type: ignore[arg-type]
            fps=p.fps,
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
        feats = {
            "fps": p.fps,
            "kinetic_mode": p.kinetic_mode,
            "geometric_frame_time_s": p.geometric_frame_time_s,
            "origin": p.fid_origin,
        }
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


def _beat_metrics(
    seqs: list[EvalSequence],
    p: EvaluateParams,
    out: list[MetricResult],
    unscored: dict[str, list[dict[str, str]]],
) -> None:
    step = round(p.fps / p.msd_fps)  # an integer ratio (checked by EvaluateParams)
    per: dict[str, list[tuple[str, float]]] = defaultdict(list)
    for s in seqs:
        pos, beats = s.gen_positions, s.music_beats
        assert pos is not None and beats is not None
        mint_beats = beats
        if p.bas_beats == "whole_track_mint":
            if s.music_beats_track is None:
                raise ValueError(f"{s.seq_id}: bas_beats whole_track_mint needs the track's beats")
            mint_beats = s.music_beats_track
        mint = {"sigma": p.bas_sigma, "order": p.mint_order, "beats": p.bas_beats}
        if s.gen_positions_before is not None and len(s.gen_positions_before):
            # mint finds motion beats on the whole clip, then drops the first frames
            skip = len(s.gen_positions_before)
            whole = np.concatenate([s.gen_positions_before, pos])
            score = bas_mint(whole, mint_beats + skip, skip_frames=skip, **mint)  # type: ignore[arg-type]
        else:
            score = bas_mint(pos, mint_beats, **mint)  # type: ignore[arg-type]
        per["bas_mint"].append((s.seq_id, score))
        per["bas_bailando"].append(
            (
                s.seq_id,
                bas_bailando(
                    pos, beats, sigma=p.bas_sigma, smoothing_sigma=p.bailando_smoothing_sigma
                ),
            )
        )
        low = pos[::step]
        motion = motion_beats_choreograph(low, p.msd_fps)
        music = decimate_beats(beats[beats < pos.shape[0]], step)
        m2m, a2m = bas_msd(motion, music)
        per["bas_msd_motion2music"].append((s.seq_id, m2m))
        per["bas_msd_music2motion"].append((s.seq_id, a2m))
        counts = beat_counts(
            pos,
            beats,
            tol=p.beat_tol,
            detector=p.beat_detector,  # type: ignore[arg-type]
            order=p.mint_order,
        )
        per["beat_coverage"].append((s.seq_id, counts.coverage))
        per["beat_hit_rate"].append((s.seq_id, counts.hit_rate))
        per["beat_accuracy"].append((s.seq_id, counts.accuracy))
    conventions: dict[str, dict[str, Any]] = {
        "bas_mint": {
            "convention": "mint calculate_beat_scores.py",
            "direction": "motion2music",
            "sigma": p.bas_sigma,
            "order": p.mint_order,
            "fps": p.fps,
            "music_beats_span": p.bas_beats,
        },
        "bas_bailando": {
            "convention": "Bailando beat_align_score.py",
            "direction": "music2motion",
            "sigma": p.bas_sigma,
            "smoothing_sigma": p.bailando_smoothing_sigma,
            "fps": p.fps,
        },
        "bas_msd_motion2music": {
            "convention": "ChoreoGraph mean squared distance",
            "units": "frames^2",
            "fps": p.msd_fps,
            "beat_map": "floor(i/step+0.5)",
        },
        "bas_msd_music2motion": {
            "convention": "ChoreoGraph mean squared distance",
            "units": "frames^2",
            "fps": p.msd_fps,
            "beat_map": "floor(i/step+0.5)",
        },
    }
    counted = {
        "tol_frames": p.beat_tol,
        "matching": "greedy_one_to_one_time_order",
        "detector": p.beat_detector,
        "order": p.mint_order,
        "fps": p.fps,
    }
    for name in ("beat_coverage", "beat_hit_rate", "beat_accuracy"):
        conventions[name] = dict(counted)
    for convention in conventions.values():
        convention["music_beats"] = _BEAT_SOURCES[p.beat_source]
    frames = {s.seq_id: s.n_frames for s in seqs}
    for name in _BEAT_METRICS:
        values = []
        for seq_id, value in per[name]:
            if math.isnan(value):
                unscored[name].append({"seq_id": seq_id, "reason": "undefined: no beats to match"})
            else:
                values.append((seq_id, value))
        if not values:
            continue
        out.append(
            mean_over_units(
                name, [v for _, v in values], conventions[name], sum(frames[k] for k, _ in values)
            )
        )


def _fpd_metrics(seqs: list[EvalSequence], p: EvaluateParams, out: list[MetricResult]) -> None:
    pieces: dict[str, list[EvalSequence]] = defaultdict(list)
    if p.fpd_aggregate == "pooled":
        pieces["all"] = list(seqs)
    elif p.fpd_aggregate == "per_piece_mean":
        for s in seqs:
            pieces[s.music_id or s.seq_id].append(s)
    else:
        raise ValueError(f"fpd_aggregate must be per_piece_mean or pooled: {p.fpd_aggregate!r}")
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


def _pfc_metrics(
    seqs: list[EvalSequence], p: EvaluateParams, out: list[MetricResult], side: str
) -> None:
    """PFC of one side ("gen" or "gt") at ``pfc_fps``: positions are y up here, which gives
    EDGE's z-up value (a rotation keeps the horizontal plane and the up clamp)."""
    step = round(p.fps / p.pfc_fps)
    name = "pfc" if side == "gen" else "pfc_gt"
    positions = [getattr(s, f"{side}_positions")[::step] for s in seqs]
    result = pfc(positions, fps=p.pfc_fps, up_axis="y", clip_frames=p.pfc_clip_frames, name=name)
    if not result.n_units:
        raise ValueError("no clip with root acceleration (PFC undefined everywhere)")
    convention = {**result.convention, "source_fps": p.fps, "frame_step": step}
    out.append(
        MetricResult(
            name, result.value, convention, result.n_units, result.n_frames, result.details
        )
    )


def _multimodality_metrics(
    generations: Mapping[str, Sequence[np.ndarray]],
    seqs: list[EvalSequence],
    p: EvaluateParams,
    out: list[MetricResult],
    reference: Sequence[np.ndarray] | None,
    kind: str,
) -> None:
    """mm_k / mm_g: each group's generations (whole compared frames, one feature vector each),
    z-scored by the ground-truth units' features, as div_* is."""
    feats = {
        "fps": p.fps,
        "kinetic_mode": p.kinetic_mode,
        "geometric_frame_time_s": p.geometric_frame_time_s,
        "origin": p.fid_origin,
    }
    gt = list(reference) if reference is not None else _units(seqs, "gt_positions", False)
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
    out.append(MetricResult(name, r.value, convention, r.n_units, r.n_frames, r.details))


def _guarded(
    names: Sequence[str], skipped: dict[str, str], out: list[MetricResult], run: Callable[[], None]
) -> None:
    """Run one metric family; if the numbers cannot be computed (a ValueError or LinAlgError
    from the maths, e.g. a degenerate feature matrix), record why for each of its metrics
    instead of stopping the whole evaluation, and drop its partial results."""
    before = len(out)
    try:
        run()
    except (ValueError, np.linalg.LinAlgError) as exc:
        del out[before:]
        for name in names:
            skipped[name] = f"could not be computed: {type(exc).__name__}: {str(exc)[:200]}"


def evaluate_sequences(
    seqs: Sequence[EvalSequence],
    params: EvaluateParams,
    unreadable: Sequence[dict[str, str]] = (),
    reference_positions: Sequence[np.ndarray] | None = None,
    generations: Mapping[str, Sequence[np.ndarray]] | None = None,
) -> Evaluation:
    """Every metric of :data:`METRICS` over ``seqs``; ``unreadable`` ({seq_id, reason}) are
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
    unscored: dict[str, list[dict[str, str]]] = {name: [] for name in METRICS}
    for item in unreadable:
        for name in METRICS:
            unscored[name].append(dict(item))
    skipped: dict[str, str] = {}
    out: list[MetricResult] = []

    by_measure_mse = params.mse_reduce == "measure_mean"
    rows = _needs(
        seqs,
        ["mse"],
        "rotations",
        lambda s: s.gt_rows is not None and s.gen_rows is not None,
        unscored,
    )
    if by_measure_mse:
        rows = _needs(rows, ["mse"], "measures", lambda s: bool(s.measures), unscored)
    if rows:

        def run_mse() -> None:
            out.append(
                mse(
                    _units(rows, "gt_rows", by_measure_mse),
                    _units(rows, "gen_rows", by_measure_mse),
                    space=params.mse_space,  # type: ignore[arg-type]
                    wrap=params.mse_wrap,
                    reduce=params.mse_reduce,  # type: ignore[arg-type]
                    groups=[s.seq_id for s in rows],
                )
            )
            out[-1].convention["unit"] = "measure" if by_measure_mse else "sequence"

        _guarded(["mse"], skipped, out, run_mse)
    else:
        skipped["mse"] = "no sequence with rotations on both sides"

    positions = _needs(
        seqs,
        _FEATURE_METRICS,
        "positions",
        lambda s: s.gt_positions is not None and s.gen_positions is not None,
        unscored,
    )
    if params.fid_unit == "measure":
        positions = _needs(
            positions, _FEATURE_METRICS, "measures", lambda s: bool(s.measures), unscored
        )
    n_units = len(_units(positions, "gt_positions", params.fid_unit == "measure"))
    if n_units >= 2:
        for kind in ("kinetic", "geometric"):
            _guarded(
                [f"fid_{kind[0]}", f"div_{kind[0]}", f"div_{kind[0]}_gt"],
                skipped,
                out,
                lambda kind=kind: _feature_metrics(
                    positions, params, out, reference_positions, (kind,)
                ),
            )
    else:
        for name in _FEATURE_METRICS:
            skipped[name] = (
                f"needs joint positions of at least 2 units ({params.fid_unit}s), have {n_units}"
            )

    beats = _needs(
        [s for s in seqs if s.gen_positions is not None],
        _BEAT_METRICS,
        "music_beats",
        lambda s: s.music_beats is not None,
        unscored,
    )
    for s in seqs:
        if s.gen_positions is None:
            for name in _BEAT_METRICS:
                reason = s.missing.get("positions", "no positions")
                unscored[name].append({"seq_id": s.seq_id, "reason": reason})
    if beats:
        _guarded(_BEAT_METRICS, skipped, out, lambda: _beat_metrics(beats, params, out, unscored))
    for name in _BEAT_METRICS:
        if not any(r.name == name for r in out):
            skipped.setdefault(name, "no sequence with generated positions and music beats")

    poses = _needs(
        seqs,
        ["fpd", "fmd"],
        "rotations",
        lambda s: s.gt_axis_angle is not None and s.gen_axis_angle is not None,
        unscored,
    )
    if poses:
        _guarded(["fpd", "fmd"], skipped, out, lambda: _fpd_metrics(poses, params, out))
    else:
        skipped["fpd"] = skipped["fmd"] = "no sequence with rotations on both sides"

    for side, name in (("gen", "pfc"), ("gt", "pfc_gt")):
        usable = _needs(
            seqs,
            [name],
            "positions",
            lambda s, side=side: getattr(s, f"{side}_positions") is not None,
            unscored,
        )
        if usable:
            _guarded(
                [name], skipped, out, lambda u=usable, side=side: _pfc_metrics(u, params, out, side)
            )
        else:
            skipped[name] = "no sequence with SMPL-24 joint positions"

    if generations is None:
        for name in ("mm_k", "mm_g"):
            skipped[name] = "needs several generations per music piece (evaluate --generations)"
    else:
        for kind in ("kinetic", "geometric"):
            _guarded(
                [f"mm_{kind[0]}"],
                skipped,
                out,
                lambda kind=kind: _multimodality_metrics(
                    generations, positions, params, out, reference_positions, kind
                ),
            )

    out.sort(key=lambda r: METRICS.index(r.name))
    results = [_with_unscored(r, params) for r in out]
    return Evaluation(results, unscored, skipped)
