"""FPD and FMD (docs/METRICS.md; ChoreoGraph 004 §4.2.1, after Transflower).

Pose features are the joints' exponential maps (axis-angle, rad) concatenated per frame, with no
normalisation: FPD is the Fréchet distance between the generated and the real pose
distributions, FMD the same over concatenations of three consecutive poses.

Two conventions (``parity``):

* ``"spec"`` (default): per clip, frames decimated to ``frame_step`` (60 → 20 fps is 3), FMD on
  *sliding* triples (p_{i−1}, p_i, p_{i+1}), i = 1 … T−2 within each clip; moments are mean and
  ``np.cov``; the Fréchet distance retries with ε = 1e−6 on a non-finite square root.
* ``"transflower"``: Transflower ``extract_transform.py`` (``2moments``, ``2moments_ext``) and
  ``analysis/sandbox_fid.py`` (``FID``): frames of all clips pooled first; the second moment is
  the *uncentred* XᵀX/N; FMD triples are *non-overlapping* (the pooled frames truncated to a
  multiple of 3, reshaped to (−1, 3D)); no ε retry. Its deletion of two constant columns of its
  67-d expmap layout does not apply to SMPL-24 and is not done.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Literal

import numpy as np

from dancedata.metrics.frechet import frechet_distance
from dancedata.metrics.result import MetricResult

__all__ = ["fmd", "fpd", "pose_frames", "pose_triples"]

Parity = Literal["spec", "transflower"]


def _clip(clip: np.ndarray, frame_step: int) -> np.ndarray:
    x = np.asarray(clip, dtype=np.float64)
    if x.ndim == 3:
        x = x.reshape(x.shape[0], -1)
    if x.ndim != 2:
        raise ValueError(f"pose clip must be (F, J, 3) or (F, D), got {np.shape(clip)}")
    return x[::frame_step]


def pose_frames(clips: Sequence[np.ndarray], frame_step: int = 3) -> np.ndarray:
    """(ΣF', D) pooled pose rows: each clip's axis-angle frames (every ``frame_step``-th)."""
    rows = [_clip(c, frame_step) for c in clips]
    if not rows:
        raise ValueError("no pose clips")
    return np.concatenate(rows, axis=0)


def pose_triples(
    clips: Sequence[np.ndarray], frame_step: int = 3, parity: Parity = "spec"
) -> np.ndarray:
    """(n, 3D) triples of consecutive pose rows: sliding within each clip (``spec``) or
    non-overlapping over the pooled frames (``transflower``)."""
    if parity == "transflower":
        pooled = pose_frames(clips, frame_step)
        n = pooled.shape[0] - pooled.shape[0] % 3
        return pooled[:n].reshape(-1, 3 * pooled.shape[1])
    if parity != "spec":
        raise ValueError(f"parity must be 'spec' or 'transflower', got {parity!r}")
    triples = []
    for clip in clips:
        x = _clip(clip, frame_step)
        if x.shape[0] >= 3:
            triples.append(np.concatenate([x[:-2], x[1:-1], x[2:]], axis=1))
    if not triples:
        raise ValueError("no clip has 3 frames for a triple")
    return np.concatenate(triples, axis=0)


def _distance(
    name: str, evaluated: np.ndarray, reference: np.ndarray, parity: Parity, frames: int
) -> MetricResult:
    transflower = parity == "transflower"
    result = frechet_distance(
        evaluated,
        reference,
        name=name,
        normalize=False,
        moments_kind="uncentred" if transflower else "covariance",
        eps=None if transflower else 1e-6,
        n_frames=frames,
    )
    return result


def fpd(
    generated: Sequence[np.ndarray],
    real: Sequence[np.ndarray],
    *,
    frame_step: int = 3,
    parity: Parity = "spec",
) -> MetricResult:
    """Fréchet Pose Distance between generated and real clips of (F, J, 3) axis-angle poses (or
    (F, D) pose rows). Convention: parity, frame_step, moments, eps, no normalisation."""
    result = _distance(
        "fpd",
        pose_frames(generated, frame_step),
        pose_frames(real, frame_step),
        parity,
        sum(int(np.shape(c)[0]) for c in generated),
    )
    convention = {**result.convention, "parity": parity, "frame_step": frame_step}
    return MetricResult(
        "fpd",
        result.value,
        convention,
        len(generated),
        result.n_frames,
        {**result.details, "n_samples": result.n_units},
    )


def fmd(
    generated: Sequence[np.ndarray],
    real: Sequence[np.ndarray],
    *,
    frame_step: int = 3,
    parity: Parity = "spec",
) -> MetricResult:
    """Fréchet Motion Distance: :func:`fpd` on triples of consecutive poses
    (:func:`pose_triples`)."""
    result = _distance(
        "fmd",
        pose_triples(generated, frame_step, parity),
        pose_triples(real, frame_step, parity),
        parity,
        sum(int(np.shape(c)[0]) for c in generated),
    )
    triples = "non_overlapping_pooled" if parity == "transflower" else "sliding_per_clip"
    convention = {
        **result.convention,
        "parity": parity,
        "frame_step": frame_step,
        "triples": triples,
    }
    return MetricResult(
        "fmd",
        result.value,
        convention,
        len(generated),
        result.n_frames,
        {**result.details, "n_samples": result.n_units},
    )
