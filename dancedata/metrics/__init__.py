"""The metrics (docs/METRICS.md), each a pure function named by its convention and returning
a :class:`MetricResult` (value + convention + sample size).

- :mod:`.mse` — reconstruction MSE with space, wrapping and reduction.
- :mod:`.frechet` — the Fréchet distance as mint computes it, reference z-scoring.
- :mod:`.fid` — FID_k / FID_g on the AIST++ kinetic / geometric features.
- :mod:`.diversity` — mean pairwise feature distance.
- :mod:`.beats` — bas_mint, bas_bailando, ChoreoGraph's two MSDs, coverage / hit / accuracy.
- :mod:`.fpd` — FPD and FMD (ChoreoGraph after Transflower).
- :mod:`.pfc` — EDGE's Physical Foot Contact score.
- :mod:`.multimodality` — mean distance between generations for the same music.
- :mod:`.reconstruction_error` — the MSE of docs/EXPERIMENTS.md §4.1 in its default convention.
- :mod:`.evaluate_inputs` — the conversions that put generated and ground-truth motion into
  the spaces the metrics read; :mod:`.evaluate_conventions` — the settings of a paper's table
  row (the scoring itself, over the metric registry: :mod:`dancedata.study.scoring`).
"""

from dancedata.metrics.beats import (
    BeatCounts,
    bas_bailando,
    bas_mint,
    bas_msd,
    beat_counts,
    beat_frames,
    greedy_beat_matching,
    motion_beats_choreograph,
)
from dancedata.metrics.diversity import diversity
from dancedata.metrics.fid import fid, motion_feature_matrix
from dancedata.metrics.fpd import fmd, fpd
from dancedata.metrics.frechet import frechet_distance, reference_normalization
from dancedata.metrics.mse import mse
from dancedata.metrics.multimodality import multimodality
from dancedata.metrics.pfc import pfc
from dancedata.metrics.result import MetricResult, mean_over_units

__all__ = [
    "BeatCounts",
    "MetricResult",
    "bas_bailando",
    "bas_mint",
    "bas_msd",
    "beat_counts",
    "beat_frames",
    "diversity",
    "fid",
    "fmd",
    "fpd",
    "frechet_distance",
    "greedy_beat_matching",
    "mean_over_units",
    "motion_beats_choreograph",
    "motion_feature_matrix",
    "mse",
    "multimodality",
    "pfc",
    "reference_normalization",
]
