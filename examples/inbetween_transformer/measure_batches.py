"""Measure windows from ``dancedata.read.torch_data.MeasureDataset``, with their keyframe baseline.

Every window is one complete measure of one sequence (60 fps, 225-d FACT rows). For each window this
module computes ``X_lin`` (docs/EXPERIMENTS.md §3.3): the evenly spaced keyframes
``floor(k(L−1)/(N−1) + 0.5)`` (§2.2, first and last frame included) interpolated by linear
translation + quaternion SLERP (§3.1, ``dancedata.methods.inbetween.linear_slerp``), in the 225-d
layout.

Measures differ in length (14400/BPM frames). Batching is done here, in :func:`collate`: each
batch is padded to its longest window with zeros and a key-padding mask; a window longer than
the model's ``max_len`` is cropped to its first ``max_len`` frames for training (counted by
``train.py``). The library's ``dancedata.read.torch_batching.pad_collate`` pads motion and audio the
same way; this collate exists because each item also carries its precomputed X_lin and target.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import torch

from dancedata.compute.rotations import rotmat_to_quat
from dancedata.methods.inbetween import linear_slerp, segment_map
from dancedata.methods.keyframes import even_indices
from dancedata.read.torch_data import MeasureDataset

# Audio per variant: the thesis's 22-d M_full of the full mix, or of the drums stem (the first
# 22 columns of thesis_stems_88, stems in contract order drums, bass, vocals, other).
AUDIO_VIEW = {"full": ("thesis_audio_22", slice(0, 22)), "drum": ("thesis_stems_88", slice(0, 22))}


def audio_kind(variant: str) -> str | None:
    """``full`` / ``drum`` for the audio variants, None otherwise."""
    return variant.rsplit("_", 1)[1] if variant.startswith(("merged", "cross")) else None


def keyframe_baseline(rows: np.ndarray, keyframes: np.ndarray) -> np.ndarray:
    """(L, 225) FACT rows + (N,) local keyframes (first 0, last L−1) → (L, 225) X_lin: linear
    translation + shortest-arc quaternion SLERP between consecutive keyframes (float64)."""
    rows = np.asarray(rows, dtype=np.float64)
    length = rows.shape[0]
    seg = segment_map(np.array([0]), np.array([length]), np.asarray(keyframes)[None, :])
    quat = rotmat_to_quat(rows[:, 9:].reshape(length, 24, 3, 3))
    return linear_slerp(quat, rows[:, 6:9], seg).rotmat225()


@dataclass
class Window:
    """One measure: ground truth, X_lin, conditioning, and where it sits in its sequence."""

    seq_id: str
    measure: int
    frame_start: int
    motion: np.ndarray  # (L, 225) float32 ground truth
    x_lin: np.ndarray  # (L, 225) float32
    genre: np.ndarray  # (G,) float32
    audio: np.ndarray | None  # (L, 22) float32 or None


def load_windows(
    store: str, split: str, n_keyframes: int, variant: str, version: str | None = None
) -> tuple[list[Window], object]:
    """Every measure window of ``split`` (crossmodal scheme) through ``MeasureDataset``, with
    X_lin for ``n_keyframes`` even keyframes; also returns the dataset's ``DanceStore``.
    Audio variants see only measures the audio covers (as ``iter_measures`` does)."""
    kind = audio_kind(variant)
    view, columns = AUDIO_VIEW[kind] if kind else (None, slice(0))
    dataset = MeasureDataset(store, split=split, audio=view, version=version)
    windows = []
    for i in range(len(dataset)):
        item = dataset[i]
        motion = item["motion"].numpy()
        length = motion.shape[0]
        x_lin = keyframe_baseline(motion, even_indices(length, n_keyframes))
        audio = item["audio"].numpy()[:, columns] if kind else None
        windows.append(
            Window(
                item["seq_id"],
                int(item["measure"]),
                int(item["frame_start"]),
                motion.astype(np.float32),
                x_lin.astype(np.float32),
                item["genre"].numpy().astype(np.float32),
                audio,
            )
        )
    return windows, dataset.store


def audio_stats(windows: list[Window]) -> tuple[list[float], list[float]] | None:
    """Per-channel mean and standard deviation of the windows' audio (train split), for
    z-scoring ([CHOICE]: the thesis does not say; raw MFCCs are in the hundreds)."""
    if not windows or windows[0].audio is None:
        return None
    values = np.concatenate([w.audio for w in windows], axis=0).astype(np.float64)
    std = values.std(axis=0)
    return values.mean(axis=0).tolist(), np.where(std > 1e-8, std, 1.0).tolist()


def collate(
    windows: list[Window], max_len: int, stats: tuple[list[float], list[float]] | None
) -> dict[str, torch.Tensor]:
    """Pad (zeros) to the batch's longest window, cropped to ``max_len``; ``pad_mask`` is True
    at padded frames. Keys: x_lin, target (the residual motion − X_lin), genre, audio, pad_mask."""
    t = min(max(w.motion.shape[0] for w in windows), max_len)
    b = len(windows)
    x_lin = np.zeros((b, t, 225), np.float32)
    target = np.zeros((b, t, 225), np.float32)
    pad = np.ones((b, t), bool)
    audio = None
    if stats is not None:
        mean, std = np.asarray(stats[0], np.float32), np.asarray(stats[1], np.float32)
        audio = np.zeros((b, t, len(mean)), np.float32)
    for i, w in enumerate(windows):
        n = min(w.motion.shape[0], t)
        x_lin[i, :n] = w.x_lin[:n]
        target[i, :n] = w.motion[:n] - w.x_lin[:n]
        pad[i, :n] = False
        if audio is not None and w.audio is not None:
            audio[i, :n] = (w.audio[:n] - mean) / std
    return {
        "x_lin": torch.from_numpy(x_lin),
        "target": torch.from_numpy(target),
        "genre": torch.from_numpy(np.stack([w.genre for w in windows])),
        "audio": None if audio is None else torch.from_numpy(audio),
        "pad_mask": torch.from_numpy(pad),
    }
