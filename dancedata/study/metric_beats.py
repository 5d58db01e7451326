"""The beat scores (docs/METRICS.md, "Beat scores"): ``bas_mint``, ``bas_bailando``,
``bas_msd_motion2music``, ``bas_msd_music2motion``, ``beat_coverage``, ``beat_hit_rate``,
``beat_accuracy``, each under its own name and convention.

Needs the generated SMPL-24 positions and the music beats; per-sequence values averaged over
sequences (a sequence whose value is undefined, e.g. no beats to match, is listed unscored).
The maths is :mod:`dancedata.metrics.beats`.
"""

from __future__ import annotations

import math
from collections import defaultdict
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

from dancedata.errors import InputError
from dancedata.featurize.family_settings import setting
from dancedata.study.metric_registry import (
    EvalSequence,
    Metric,
    MetricInputs,
    ScoringSettings,
    check_choices,
    register_metric,
)

if TYPE_CHECKING:
    from dancedata.metrics.result import MetricResult

BEAT_SOURCES = {  # beat_source -> the store array and its recipe, recorded
    "fact": "audio/beats (FACT: librosa beat_track, start_bpm = music BPM)",
    "bailando": "audio/beats_bailando (Bailando: HPSS percussive, median onset, beat_track)",
}


@dataclass(frozen=True)
class BeatSettings:
    """σ, orders, tolerances and the music beats of the beat scores."""

    bas_sigma: float = setting(3.0, help="σ (frames) of bas_mint / bas_bailando.")
    mint_order: int = 10
    bailando_smoothing_sigma: float = 5.0
    beat_source: str = setting(
        "fact",
        help="Music beats of every beat metric: fact (audio/beats, the store's default) or "
        "bailando (audio/beats_bailando: featurize --audio-families bailando_beats).",
    )
    bas_beats: str = setting(
        "motion_span",
        help="Music beats bas_mint matches: motion_span (beats inside the compared frames) "
        "or whole_track_mint (also the track's beats after the last motion frame, as mint "
        "scores generated motion).",
    )
    beat_tol: int = setting(12, help="Beat coverage / hit / accuracy tolerance (frames).")
    beat_detector: str = setting(
        "mint", help="Motion beats for coverage / hit / accuracy: mint or bailando."
    )
    msd_fps: float = setting(20.0, help="Frame rate of ChoreoGraph's beat MSD.")

    def __post_init__(self) -> None:
        check_choices(
            self,
            {
                "bas_beats": ("motion_span", "whole_track_mint"),
                "beat_source": ("fact", "bailando"),
                "beat_detector": ("mint", "bailando"),
            },
        )
        if self.beat_tol < 0:
            raise InputError("skip_frames and beat_tol must be ≥ 0, fpd_frame_step ≥ 1")

    def check(self, scoring: ScoringSettings) -> None:
        scoring.frame_step("msd_fps", self.msd_fps)


def _conventions(p: BeatSettings, fps: float) -> dict[str, dict[str, Any]]:
    msd = {
        "convention": "ChoreoGraph mean squared distance",
        "units": "frames^2",
        "fps": p.msd_fps,
        "beat_map": "floor(i/step+0.5)",
    }
    conventions: dict[str, dict[str, Any]] = {
        "bas_mint": {
            "convention": "mint calculate_beat_scores.py",
            "direction": "motion2music",
            "sigma": p.bas_sigma,
            "order": p.mint_order,
            "fps": fps,
            "music_beats_span": p.bas_beats,
        },
        "bas_bailando": {
            "convention": "Bailando beat_align_score.py",
            "direction": "music2motion",
            "sigma": p.bas_sigma,
            "smoothing_sigma": p.bailando_smoothing_sigma,
            "fps": fps,
        },
        "bas_msd_motion2music": dict(msd),
        "bas_msd_music2motion": dict(msd),
    }
    counted = {
        "tol_frames": p.beat_tol,
        "matching": "greedy_one_to_one_time_order",
        "detector": p.beat_detector,
        "order": p.mint_order,
        "fps": fps,
    }
    for name in ("beat_coverage", "beat_hit_rate", "beat_accuracy"):
        conventions[name] = dict(counted)
    for convention in conventions.values():
        convention["music_beats"] = BEAT_SOURCES[p.beat_source]
    return conventions


def _per_sequence(s: EvalSequence, p: BeatSettings, fps: float) -> dict[str, float]:
    """Every beat score of one sequence."""
    import numpy as np

    from dancedata.metrics.beats import (
        bas_bailando,
        bas_mint,
        bas_msd,
        beat_counts,
        decimate_beats,
        motion_beats_choreograph,
    )

    step = round(fps / p.msd_fps)  # an integer ratio (checked by BeatSettings.check)
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
    out = {"bas_mint": score}
    out["bas_bailando"] = bas_bailando(
        pos, beats, sigma=p.bas_sigma, smoothing_sigma=p.bailando_smoothing_sigma
    )
    motion = motion_beats_choreograph(pos[::step], p.msd_fps)
    music = decimate_beats(beats[beats < pos.shape[0]], step)
    out["bas_msd_motion2music"], out["bas_msd_music2motion"] = bas_msd(motion, music)
    counts = beat_counts(
        pos,
        beats,
        tol=p.beat_tol,
        detector=p.beat_detector,  # type: ignore[arg-type]
        order=p.mint_order,
    )
    out["beat_coverage"] = counts.coverage
    out["beat_hit_rate"] = counts.hit_rate
    out["beat_accuracy"] = counts.accuracy
    return out


@register_metric("beats")
class BeatMetrics(Metric):
    outputs = (
        "bas_mint",
        "bas_bailando",
        "bas_msd_motion2music",
        "bas_msd_music2motion",
        "beat_coverage",
        "beat_hit_rate",
        "beat_accuracy",
    )
    needs = ("gen_positions", "music_beats")
    settings_type = BeatSettings
    rank = 30
    unit_range = ("beat_hit_rate", "beat_accuracy", "bas_mint", "bas_bailando")
    range_notes = {  # metrics/beats.py: coverage is a ratio of two counts, not a fraction of one
        "beat_coverage": "= motion beats / music beats (B_k / B_m), not a fraction: above 1 the "
        "motion has more kinematic beats than the music has beats",
    }

    def compute(self, inputs: MetricInputs, settings: BeatSettings) -> list[MetricResult]:
        beats = inputs.usable(self.outputs, "music_beats", inputs.having("gen_positions"))
        inputs.usable(self.outputs, "gen_positions")  # lists those without generated positions
        out: list[MetricResult] = []
        if beats:
            out = inputs.guard(self.outputs, lambda: self._scores(beats, inputs, settings))
        for name in self.outputs:
            if not any(r.name == name for r in out):
                inputs.skipped.setdefault(
                    name, "no sequence with generated positions and music beats"
                )
        return out

    def _scores(
        self, seqs: list[EvalSequence], inputs: MetricInputs, p: BeatSettings
    ) -> list[MetricResult]:
        from dancedata.metrics.result import mean_over_units

        fps = inputs.params.fps
        per: dict[str, list[tuple[str, float]]] = defaultdict(list)
        for s in seqs:
            for name, value in _per_sequence(s, p, fps).items():
                per[name].append((s.seq_id, value))
        conventions = _conventions(p, fps)
        frames = {s.seq_id: s.n_frames for s in seqs}
        out = []
        for name in self.outputs:
            values = []
            for seq_id, value in per[name]:
                if math.isnan(value):
                    inputs.unscored[name].append(
                        {"seq_id": seq_id, "reason": "undefined: no beats to match"}
                    )
                else:
                    values.append((seq_id, value))
            if not values:
                continue
            total = sum(frames[k] for k, _ in values)
            out.append(mean_over_units(name, [v for _, v in values], conventions[name], total))
        return out
