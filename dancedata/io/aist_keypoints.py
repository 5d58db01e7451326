"""Read AIST++ keypoint pickles: ``keypoints3d/<seq>.pkl`` and ``keypoints2d/<seq>.pkl``.

Through the restricted unpickler, like the motion pickles. AIST++ leaves NaN where a keypoint
could not be triangulated or detected (whole frames of ``keypoints3d``, runs of frames in one
view of ``keypoints2d``), so NaN is kept; Inf is refused.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from dancedata.errors import InputError
from dancedata.io.aist import checked_array
from dancedata.io.safe_pickle import load_restricted

N_KEYPOINTS = 17  # COCO-17
N_VIEWS = 9  # AIST++ cameras c01..c09
CM_PER_M = 100.0


@dataclass(frozen=True)
class AistKeypoints3d:
    """Both 3-d keypoint sets of a sequence, converted from cm to metres (y up)."""

    keypoints3d: np.ndarray  # (F, 17, 3) float32, metres; NaN where AIST++ has none
    keypoints3d_optim: np.ndarray  # (F, 17, 3) float32, metres

    @property
    def n_frames(self) -> int:
        return int(self.keypoints3d.shape[0])


@dataclass(frozen=True)
class AistKeypoints2d:
    """Per-view 2-d detections of a sequence, frames first."""

    keypoints2d: np.ndarray  # (F, 9, 17, 3) float32: x, y in pixels, confidence in [0, 1]
    det_scores: np.ndarray  # (F, 9) float32, person detection score per view
    timestamps_us: np.ndarray  # (F,) int64, microseconds

    @property
    def n_frames(self) -> int:
        return int(self.keypoints2d.shape[0])


def _load_dict(path: Path) -> dict:
    data = load_restricted(path)
    if not isinstance(data, dict):
        raise InputError(f"expected a dict of arrays, found {type(data).__name__}", path)
    return data


def read_keypoints3d(path: str | Path) -> AistKeypoints3d:
    """``keypoints3d`` and ``keypoints3d_optim``, each (N, 17, 3) in cm → metres, float32."""
    path = Path(path)
    data = _load_dict(path)
    tail = (N_KEYPOINTS, 3)
    raw = checked_array(data, "keypoints3d", path, tail, allow_nan=True)
    optim = checked_array(data, "keypoints3d_optim", path, tail, allow_nan=True)
    if raw.shape[0] != optim.shape[0]:
        raise InputError(
            f"keypoints3d has {raw.shape[0]} frames but keypoints3d_optim has {optim.shape[0]}",
            path,
        )
    return AistKeypoints3d(
        keypoints3d=(raw.astype(np.float64) / CM_PER_M).astype(np.float32),
        keypoints3d_optim=(optim.astype(np.float64) / CM_PER_M).astype(np.float32),
    )


def read_keypoints2d(path: str | Path) -> AistKeypoints2d:
    """``keypoints2d`` (9, N, 17, 3), ``det_scores`` (9, N), ``timestamps`` (N,) µs, moved to
    frames-first layout: (N, 9, 17, 3) and (N, 9)."""
    path = Path(path)
    data = _load_dict(path)
    keypoints = checked_array(
        data, "keypoints2d", path, (N_KEYPOINTS, 3), lead=N_VIEWS, allow_nan=True
    )
    n_frames = keypoints.shape[1]
    scores = checked_array(data, "det_scores", path, (), lead=N_VIEWS, allow_nan=True)
    if scores.shape[1] != n_frames:
        raise InputError(
            f"det_scores has {scores.shape[1]} frames but keypoints2d has {n_frames}", path
        )
    if "timestamps" in data:
        stamps = checked_array(data, "timestamps", path, ())
        if stamps.shape[0] != n_frames:
            raise InputError(
                f"timestamps has {stamps.shape[0]} frames but keypoints2d has {n_frames}", path
            )
    else:
        stamps = np.round(np.arange(n_frames) * 1e6 / 60.0)
    return AistKeypoints2d(
        keypoints2d=np.ascontiguousarray(np.moveaxis(keypoints, 0, 1), dtype=np.float32),
        det_scores=np.ascontiguousarray(scores.T, dtype=np.float32),
        timestamps_us=np.asarray(stamps, dtype=np.int64),
    )
