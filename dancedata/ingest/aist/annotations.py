"""AIST++ keypoint annotations: read and checked per sequence, and their rows in the stored arrays.

Which annotation kinds the store gets is decided once from the files on disk: a kind is stored
when at least one selected sequence has a file for it. Sequences without that file get NaN
rows of the right length, and the sequences table says which is which (``has_keypoints3d``,
``has_keypoints2d``), so frames stay aligned with ``motion/trans`` for every array.

    motion/keypoints3d        (F, 17, 3)     float32  metres (AIST++ cm / 100), NaN: none
    motion/keypoints3d_optim  (F, 17, 3)     float32  metres
    motion/keypoints2d        (F, 9, 17, 3)  float32  x, y pixels, confidence; NaN: none
    motion/det_scores         (F, 9)         float32  person detection score per view

The keypoints are checked as stored (after cm -> m and the float32 cast, where a finite float64
such as 1e300 becomes Inf): NaN is kept, Inf is refused, keypoints3d stay within ±1000 m and
keypoints2d / det_scores within ±1e6 (an overflow guard). See dancedata.io.aist.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from dancedata.compute.smpl import COCO17_KEYPOINTS, COCO17_PARENTS
from dancedata.errors import InputError
from dancedata.ingest.source import StoredArray
from dancedata.io.aist import MAX_ABS_KEYPOINTS3D_M, MAX_ABS_PIXELS, check_stored
from dancedata.io.aist_keypoints import (
    N_KEYPOINTS,
    N_VIEWS,
    AistKeypoints2d,
    AistKeypoints3d,
    read_keypoints2d,
    read_keypoints3d,
)

ANNOTATION_KINDS: tuple[str, ...] = ("keypoints3d", "keypoints2d", "cameras")
VIEW_NAMES: tuple[str, ...] = tuple(f"c{i:02d}" for i in range(1, N_VIEWS + 1))
# Whole chunks written per zarr call: zarr compresses them in parallel threads (about 2× the
# write throughput on 2 CPUs); memory 4 × 15 MB for keypoints2d.
CHUNKS_PER_WRITE = 4
# keypoints2d timestamps may differ from i × 1e6 / fps by this much (they are rounded to µs).
TIMESTAMP_TOLERANCE_US = 2.0


@dataclass(frozen=True)
class SequenceAnnotations:
    """The keypoint annotations read for one sequence (None where the file is absent)."""

    keypoints3d: AistKeypoints3d | None
    keypoints2d: AistKeypoints2d | None


def read_annotations(
    kp3d_path: Path | None, kp2d_path: Path | None, n_frames: int, fps: float
) -> SequenceAnnotations:
    """Read a sequence's keypoint pickles and check they match its ``n_frames`` motion frames
    at ``fps`` and that what will be stored is finite (NaN allowed) and in range (InputError
    naming the file otherwise)."""
    with np.errstate(over="ignore"):  # overflow to Inf in the float32 cast: check_stored finds it
        kp3d = read_keypoints3d(kp3d_path) if kp3d_path is not None else None
        kp2d = read_keypoints2d(kp2d_path) if kp2d_path is not None else None
    if kp3d is not None:
        if kp3d.n_frames != n_frames:
            raise InputError(
                f"keypoints3d has {kp3d.n_frames} frames but the motion has {n_frames}",
                kp3d_path,
            )
        for label, values in (
            ("keypoints3d", kp3d.keypoints3d),
            ("keypoints3d_optim", kp3d.keypoints3d_optim),
        ):
            check_stored(label, values, kp3d_path, MAX_ABS_KEYPOINTS3D_M, units="m", allow_nan=True)
    if kp2d is not None:
        for label, values in (("keypoints2d", kp2d.keypoints2d), ("det_scores", kp2d.det_scores)):
            check_stored(label, values, kp2d_path, MAX_ABS_PIXELS, allow_nan=True)
        if kp2d.n_frames != n_frames:
            raise InputError(
                f"keypoints2d has {kp2d.n_frames} frames but the motion has {n_frames}", kp2d_path
            )
        expected = np.arange(n_frames) * 1e6 / fps
        offset = kp2d.timestamps_us.astype(np.float64) - kp2d.timestamps_us[0]
        worst = float(np.max(np.abs(offset - expected))) if n_frames else 0.0
        if worst > TIMESTAMP_TOLERANCE_US:
            raise InputError(
                f"keypoints2d timestamps are not at {fps:g} fps (off by up to {worst:.0f} µs)",
                kp2d_path,
            )
    return SequenceAnnotations(kp3d, kp2d)


def annotation_arrays(keypoints3d: bool, keypoints2d: bool) -> list[StoredArray]:
    """The stored keypoint arrays, for the kinds some selected sequence has a file for."""
    skeleton = {
        "name": "coco17",
        "joints": list(COCO17_KEYPOINTS),
        "parents": list(COCO17_PARENTS),
    }
    specs: list[StoredArray] = []
    if keypoints3d:
        for name, note in (
            ("keypoints3d", "triangulated"),
            ("keypoints3d_optim", "after AIST++ bundle optimisation"),
        ):
            specs.append(
                StoredArray(
                    name,
                    (N_KEYPOINTS, 3),
                    np.float32,
                    attrs={"units": "m", "skeleton": skeleton, "note": note, "missing": "NaN"},
                    chunks_per_write=CHUNKS_PER_WRITE,
                )
            )
    if keypoints2d:
        specs.append(
            StoredArray(
                "keypoints2d",
                (N_VIEWS, N_KEYPOINTS, 3),
                np.float32,
                attrs={
                    "units": "px",
                    "channels": ["x", "y", "confidence"],
                    "views": list(VIEW_NAMES),
                    "layout": "frames, views, keypoints, channels",
                    "skeleton": skeleton,
                    "missing": "NaN",
                },
                chunks_per_write=CHUNKS_PER_WRITE,
            )
        )
        specs.append(
            StoredArray(
                "det_scores",
                (N_VIEWS,),
                np.float32,
                attrs={"views": list(VIEW_NAMES), "missing": "NaN"},
                chunks_per_write=CHUNKS_PER_WRITE,
            )
        )
    return specs


def annotation_rows(
    annotations: SequenceAnnotations, n_frames: int, stored: list[StoredArray]
) -> tuple[dict[str, np.ndarray], dict[str, Any]]:
    """One sequence's rows of the ``stored`` keypoint arrays (NaN where its file is absent),
    and its sequences-table columns."""
    kp3d, kp2d = annotations.keypoints3d, annotations.keypoints2d
    values: dict[str, np.ndarray | None] = {
        "keypoints3d": None if kp3d is None else kp3d.keypoints3d,
        "keypoints3d_optim": None if kp3d is None else kp3d.keypoints3d_optim,
        "keypoints2d": None if kp2d is None else kp2d.keypoints2d,
        "det_scores": None if kp2d is None else kp2d.det_scores,
    }
    rows: dict[str, np.ndarray] = {}
    for spec in stored:
        block = values[spec.name]
        if block is None:
            block = np.full((n_frames, *spec.row_shape), np.nan, dtype=np.float32)
        rows[spec.name] = block
    nan_frames = (
        int(np.isnan(kp3d.keypoints3d).any(axis=(1, 2)).sum()) if kp3d is not None else None
    )
    return rows, {
        "has_keypoints3d": kp3d is not None,
        "has_keypoints2d": kp2d is not None,
        "keypoints3d_nan_frames": nan_frames,
    }
