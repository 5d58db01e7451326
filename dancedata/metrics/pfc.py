"""EDGE's Physical Foot Contact score, PFC (docs/METRICS.md, "PFC"; EDGE ``eval/eval_pfc.py``).

Lower is better: a body that accelerates while neither foot is still is implausible. Per clip
of F frames at frame time Δt (SMPL-24 joint positions, metres):

    a_t = ‖ā_t‖ / max_t ‖ā_t‖,   ā_t = (r_{t+1} − 2 r_t + r_{t−1}) / Δt²  with its up component
          clamped to ≥ 0 (falling is free, pushing up is not)           r = root joint, t = 1..F−2
    v_t^j = ‖h(x^j_{t+1} − x^j_t)‖   the horizontal displacement (metres per frame, not per
          second) of foot joint j ∈ {7 lankle, 10 ltoes, 8 rankle, 11 rtoes}, t = 1..F−2
    PFC_clip = mean_t [ min(v^7, v^10) · min(v^8, v^11) · a_t ]
    PFC = 10⁴ · mean over clips

Because the feet enter as per-frame displacements, the value depends on the frame rate (EDGE:
30 fps; at 60 fps each factor halves) and, through the per-clip max normalisation, on the clip
length: both are recorded. A clip whose root never accelerates has no normalisation (EDGE
divides 0 by 0): it is undefined (NaN) and counted in ``details["n_undefined"]``. EDGE samples
1000 clips at random when it has more; here every clip is scored.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Literal

import numpy as np

from dancedata.metrics.result import MetricResult

__all__ = ["PFC_FOOT_JOINTS", "pfc", "pfc_clip", "pfc_clips"]

PFC_FOOT_JOINTS: tuple[int, int, int, int] = (7, 10, 8, 11)  # lankle, ltoes, rankle, rtoes
PFC_SCALE = 1e4
_UP = {"x": 0, "y": 1, "z": 2}


def pfc_clip(positions: np.ndarray, fps: float, up_axis: Literal["y", "z"] = "z") -> float:
    """PFC of one clip before the 10⁴ scale (module docstring): (F, ≥ 12, 3) positions at
    ``fps``; NaN when F < 3 or the root never accelerates."""
    p = np.asarray(positions, dtype=np.float64)
    if p.ndim != 3 or p.shape[1] < 12 or p.shape[2] != 3:
        raise ValueError(f"need SMPL joint positions (F, 24, 3), got {p.shape}")
    if up_axis not in ("y", "z"):
        raise ValueError(f"up_axis must be y or z, got {up_axis!r}")
    if not fps > 0:
        raise ValueError(f"fps must be positive, got {fps}")
    if p.shape[0] < 3:
        return float("nan")
    up = _UP[up_axis]
    flat = [a for a in range(3) if a != up]
    dt = 1.0 / fps
    root = p[:, 0]
    acc = (root[2:] - 2.0 * root[1:-1] + root[:-2]) / (dt * dt)  # (F−2, 3)
    acc[:, up] = np.maximum(acc[:, up], 0.0)
    norm = np.linalg.norm(acc, axis=1)
    peak = float(norm.max())
    if not peak > 0:
        return float("nan")
    feet = p[:, list(PFC_FOOT_JOINTS)][:, :, flat]  # (F, 4, 2)
    step = np.linalg.norm(feet[2:] - feet[1:-1], axis=-1)  # (F−2, 4)
    left = np.minimum(step[:, 0], step[:, 1])
    right = np.minimum(step[:, 2], step[:, 3])
    return float(np.mean(left * right * (norm / peak)))


def pfc_clips(
    sequences: Sequence[np.ndarray], clip_frames: int | None
) -> list[tuple[int, np.ndarray]]:
    """Cut each (F, J, 3) sequence into consecutive clips of ``clip_frames`` frames (a shorter
    tail is dropped) or keep it whole (None); (sequence index, clip) pairs."""
    if clip_frames is not None and clip_frames < 3:
        raise ValueError(f"PFC clips need at least 3 frames, got {clip_frames}")
    out = []
    for i, seq in enumerate(sequences):
        if clip_frames is None:
            out.append((i, seq))
            continue
        for start in range(0, len(seq) - clip_frames + 1, clip_frames):
            out.append((i, seq[start : start + clip_frames]))
    return out


def pfc(
    sequences: Sequence[np.ndarray],
    *,
    fps: float,
    up_axis: Literal["y", "z"] = "z",
    clip_frames: int | None = None,
    name: str = "pfc",
) -> MetricResult:
    """PFC (× 10⁴) over the clips of ``sequences`` ((F, 24, 3) joint positions at ``fps``, the
    frame rate the score is computed at: EDGE's 30). Undefined clips are left out of the mean
    (their count in ``details``); NaN when no clip is defined."""
    clips = pfc_clips(sequences, clip_frames)
    values = np.array([pfc_clip(c, fps, up_axis) for _, c in clips], dtype=np.float64)
    defined = values[~np.isnan(values)]
    value = float(np.mean(defined) * PFC_SCALE) if defined.size else float("nan")
    convention = {
        "convention": "EDGE eval/eval_pfc.py",
        "fps": float(fps),
        "up_axis": up_axis,
        "foot_joints": list(PFC_FOOT_JOINTS),
        "clip_frames": clip_frames,
        "root_acceleration": "up component clamped >= 0, normalised by its max per clip",
        "foot_speed": "horizontal displacement per frame (m)",
        "scale": PFC_SCALE,
        "reduce": "mean_over_clips",
    }
    details: dict[str, object] = {"n_clips": len(clips)}
    if defined.size < values.size:
        details["n_undefined"] = int(values.size - defined.size)
    frames = sum(len(c) for _, c in clips)
    return MetricResult(name, value, convention, int(defined.size), int(frames), details)
