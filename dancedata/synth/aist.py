"""Write a synthetic dataset in the exact AIST++ on-disk layout.

    OUT/motions/<seq>.pkl       smpl_poses (F, 72), smpl_trans (F, 3) cm, smpl_scaling, smpl_loss
    OUT/keypoints3d/<seq>.pkl   keypoints3d, keypoints3d_optim (F, 17, 3) cm
    OUT/splits/crossmodal_{train,val,test}.txt
    OUT/ignore_list.txt
    OUT/wav/<music_id>.wav      16-bit PCM at 24 kHz (deliberately not 30720 Hz)

The dataset is built under a temporary sibling directory and renamed into place at the end, so
an interrupted run never leaves a half-written dataset behind. The same seed gives the same bytes.
"""

from __future__ import annotations

import os
import pickle
import shutil
from collections.abc import Callable
from pathlib import Path

import numpy as np

from dancedata.errors import InputError
from dancedata.synth.catalog import (
    FPS,
    PlannedSequence,
    demo_plan,
    full_plan,
    ignore_list,
    stable_seed,
)
from dancedata.synth.motion import coco17_keypoints, smpl_joint_positions, synth_smpl_motion
from dancedata.synth.music import synth_dance_music

MUSIC_SR = 24000
# Music runs this much past the end of the longest motion that uses it (≈1.5 frames at 60 fps),
# like real AIST++ where audio features come out 1–2 frames longer than the motion.
MUSIC_TAIL_S = 0.025


def _write_pickle(path: Path, value: dict) -> None:
    path.write_bytes(pickle.dumps(value, protocol=4))


def write_sequence(out: Path, planned: PlannedSequence, seed: int) -> None:
    """Write one sequence's motion and keypoints3d pickles."""
    seq_seed = stable_seed(seed, planned.seq_id)
    poses, trans_m = synth_smpl_motion(planned.n_frames, FPS, planned.bpm, seed=seq_seed)
    rng = np.random.default_rng(seq_seed)
    scaling = np.array([rng.uniform(85.0, 100.0)], dtype=np.float32)
    _write_pickle(
        out / "motions" / f"{planned.seq_id}.pkl",
        {
            "smpl_poses": poses,
            "smpl_trans": (trans_m * scaling[0]).astype(np.float32),
            "smpl_scaling": scaling,
            "smpl_loss": float(rng.uniform(0.5, 2.0)),
        },
    )
    keypoints_cm = coco17_keypoints(smpl_joint_positions(poses, trans_m), poses) * 100.0
    optim_cm = keypoints_cm + rng.normal(0.0, 0.3, keypoints_cm.shape)
    _write_pickle(
        out / "keypoints3d" / f"{planned.seq_id}.pkl",
        {"keypoints3d": keypoints_cm.astype(np.float64), "keypoints3d_optim": optim_cm},
    )


def write_music(out: Path, music_id: str, bpm: float, duration_s: float, seed: int) -> None:
    """Write one song as 16-bit PCM WAV at :data:`MUSIC_SR`."""
    import soundfile as sf

    samples = synth_dance_music(bpm, duration_s, sr=MUSIC_SR, seed=stable_seed(seed, music_id))
    sf.write(out / "wav" / f"{music_id}.wav", samples, MUSIC_SR, subtype="PCM_16", format="WAV")


def write_splits(out: Path, plan: list[PlannedSequence], seed: int) -> None:
    for split in ("train", "val", "test"):
        names = [s.seq_id for s in plan if s.split == split]
        (out / "splits" / f"crossmodal_{split}.txt").write_text(
            "".join(f"{name}\n" for name in names)
        )
    (out / "ignore_list.txt").write_text("".join(f"{n}\n" for n in ignore_list(plan, seed)))


def synth_aist(
    out: str | Path,
    *,
    n_sequences: int = 24,
    full: bool = False,
    seed: int = 0,
    progress: Callable[[int, int], None] | None = None,
    overwrite: bool = False,
) -> dict[str, int]:
    """Write a synthetic AIST++ dataset to ``out``; returns counts of what was written."""
    out = Path(out)
    if out.exists() and any(out.iterdir()) and not overwrite:
        raise InputError("output directory exists and is not empty (use --force to replace)", out)
    plan = full_plan(seed) if full else demo_plan(n_sequences, seed)
    tmp = out.with_name(f".{out.name}.tmp-{os.getpid()}")
    if tmp.exists():
        shutil.rmtree(tmp)
    for sub in ("motions", "keypoints3d", "splits", "wav"):
        (tmp / sub).mkdir(parents=True)
    try:
        songs: dict[str, float] = {}
        for planned in plan:
            seconds = planned.n_frames / FPS + MUSIC_TAIL_S
            songs[planned.music_id] = max(songs.get(planned.music_id, 0.0), seconds)
        total = len(plan) + len(songs)
        done = 0
        for music_id in sorted(songs):
            bpm = next(p.bpm for p in plan if p.music_id == music_id)
            write_music(tmp, music_id, bpm, songs[music_id], seed)
            done += 1
            if progress:
                progress(done, total)
        for planned in plan:
            write_sequence(tmp, planned, seed)
            done += 1
            if progress:
                progress(done, total)
        write_splits(tmp, plan, seed)
        if out.exists():
            shutil.rmtree(out)
        out.parent.mkdir(parents=True, exist_ok=True)
        os.rename(tmp, out)
    except BaseException:
        shutil.rmtree(tmp, ignore_errors=True)
        raise
    return {"sequences": len(plan), "songs": len(songs)}
