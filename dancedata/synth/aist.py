"""Write a synthetic dataset in the exact AIST++ on-disk layout.

    OUT/motions/<seq>.pkl        smpl_poses (F, 72), smpl_trans (F, 3) cm, smpl_scaling, smpl_loss
    OUT/keypoints3d/<seq>.pkl    keypoints3d, keypoints3d_optim (F, 17, 3) cm
    OUT/keypoints2d/<seq>.pkl    keypoints2d (9, F, 17, 3), det_scores (9, F), timestamps (F,) µs
    OUT/cameras/setting<N>.json  9 calibrated cameras per setting (translation in cm)
    OUT/cameras/mapping.txt      <seq> <setting> per line
    OUT/splits/{crossmodal,pose}_{train,val,test}.txt
    OUT/ignore_list.txt
    OUT/wav/<music_id>.wav       16-bit PCM at 24 kHz (deliberately not 30720 Hz)

The dataset is built under a temporary sibling directory and renamed into place at the end, so
an interrupted run never leaves a half-written dataset behind. The same seed gives the same bytes
whatever the number of worker processes: every file depends only on the seed and its own name.
"""

from __future__ import annotations

import ctypes
import json
import os
import pickle
import shutil
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import Any

import numpy as np

from dancedata.errors import InputError
from dancedata.exec.executors import make_executor
from dancedata.synth.cameras import setting_name, synth_camera_setting
from dancedata.synth.catalog import (
    FPS,
    GENRE_ORDER,
    PlannedSequence,
    demo_plan,
    full_plan,
    ignore_list,
    stable_seed,
)
from dancedata.synth.keypoints import synth_keypoints2d, synth_keypoints3d
from dancedata.synth.motion import coco17_keypoints, smpl_joint_positions, synth_smpl_motion
from dancedata.synth.music import synth_dance_music

MUSIC_SR = 24000
# Music runs this much past the end of the longest motion that uses it (≈1.5 frames at 60 fps),
# like real AIST++ where audio features come out 1–2 frames longer than the motion.
MUSIC_TAIL_S = 0.025
SUBDIRS = ("motions", "keypoints3d", "keypoints2d", "cameras", "splits", "wav")
# Below this many sequences a process pool costs more than it saves.
POOL_MIN_SEQUENCES = 64
SEQUENCES_PER_TASK = 16


def _write_pickle(path: Path, value: dict) -> None:
    with open(path, "wb") as handle:
        pickle.dump(value, handle, protocol=4)


def write_sequence(
    out: Path, planned: PlannedSequence, seed: int, cameras: list[dict[str, Any]]
) -> None:
    """Write one sequence's motion, keypoints3d and keypoints2d pickles; ``cameras`` are the
    setting's cameras (AIST++ JSON entries) that keypoints2d is projected through."""
    seq_seed = stable_seed(seed, planned.seq_id)
    poses, trans_m = synth_smpl_motion(
        planned.n_frames, FPS, planned.bpm, seed=seq_seed, genre=planned.genre,
        situation=planned.situation,
    )  # fmt: skip
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
    _write_pickle(
        out / "keypoints3d" / f"{planned.seq_id}.pkl", synth_keypoints3d(keypoints_cm, rng)
    )
    _write_pickle(
        out / "keypoints2d" / f"{planned.seq_id}.pkl",
        synth_keypoints2d(keypoints_cm, cameras, rng, FPS),
    )


def write_music(out: Path, music_id: str, bpm: float, duration_s: float, seed: int) -> None:
    """Write one song as 16-bit PCM WAV at :data:`MUSIC_SR`."""
    import soundfile as sf

    samples = synth_dance_music(bpm, duration_s, sr=MUSIC_SR, seed=stable_seed(seed, music_id))
    sf.write(out / "wav" / f"{music_id}.wav", samples, MUSIC_SR, subtype="PCM_16", format="WAV")


def write_splits(out: Path, plan: list[PlannedSequence], seed: int) -> None:
    """All six split files (crossmodal and pose × train/val/test) and ignore_list.txt."""
    for split in ("train", "val", "test"):
        crossmodal = [s.seq_id for s in plan if s.split == split]
        pose = [s.seq_id for s in plan if s.pose_split == split]
        (out / "splits" / f"crossmodal_{split}.txt").write_text(
            "".join(f"{n}\n" for n in crossmodal)
        )
        (out / "splits" / f"pose_{split}.txt").write_text("".join(f"{n}\n" for n in pose))
    (out / "ignore_list.txt").write_text("".join(f"{n}\n" for n in ignore_list(plan, seed)))


def camera_settings(seed: int) -> dict[str, list[dict[str, Any]]]:
    """One synthetic setting per genre: ``{setting: cameras}``."""
    return {
        setting_name(gi): synth_camera_setting(stable_seed(seed, "cameras", gi))
        for gi in range(len(GENRE_ORDER))
    }


def setting_of(planned: PlannedSequence) -> str:
    return setting_name(GENRE_ORDER.index(planned.genre))


def write_cameras(out: Path, plan: list[PlannedSequence], settings: dict[str, list]) -> None:
    """``cameras/<setting>.json`` for the settings the plan uses, and ``mapping.txt``."""
    used = sorted({setting_of(p) for p in plan})
    for setting in used:
        (out / "cameras" / f"{setting}.json").write_text(json.dumps(settings[setting]))
    (out / "cameras" / "mapping.txt").write_text(
        "".join(f"{p.seq_id} {setting_of(p)}\n" for p in plan)
    )


def _songs(plan: list[PlannedSequence]) -> dict[str, tuple[float, float]]:
    """``{music_id: (bpm, seconds)}``: each song lasts its longest sequence plus a short tail."""
    songs: dict[str, tuple[float, float]] = {}
    for planned in plan:
        seconds = planned.n_frames / FPS + MUSIC_TAIL_S
        previous = songs.get(planned.music_id, (planned.bpm, 0.0))[1]
        songs[planned.music_id] = (planned.bpm, max(previous, seconds))
    return songs


def _run_task(task: tuple[str, Path, int, Any]) -> int:
    """One unit of work (a song, or a batch of sequences); returns how many files it wrote."""
    kind, out, seed, payload = task
    if kind == "music":
        music_id, bpm, seconds = payload
        write_music(out, music_id, bpm, seconds, seed)
        return 1
    batch, settings = payload
    for planned in batch:
        write_sequence(out, planned, seed, settings[setting_of(planned)])
    return len(batch)


def _tasks(
    out: Path, plan: list[PlannedSequence], seed: int, settings: dict[str, list]
) -> Iterator[tuple[str, Path, int, Any]]:
    for music_id, (bpm, seconds) in sorted(_songs(plan).items()):
        yield ("music", out, seed, (music_id, bpm, seconds))
    for start in range(0, len(plan), SEQUENCES_PER_TASK):
        batch = plan[start : start + SEQUENCES_PER_TASK]
        needed = {setting_of(p) for p in batch}
        yield ("sequences", out, seed, (batch, {k: settings[k] for k in needed}))


def reuse_freed_memory() -> None:
    """Worker warm-up (glibc): serve the per-sequence temporaries (about 1 MB each) from the
    heap and keep freed memory for reuse, instead of fresh mmap'd pages that fault on first
    touch; the page faults cost about a third of the keypoint synthesis. No-op elsewhere."""
    try:
        libc = ctypes.CDLL("libc.so.6")
        m_trim_threshold, m_mmap_threshold = -1, -3  # malloc.h
        libc.mallopt(m_mmap_threshold, 64 << 20)
        libc.mallopt(m_trim_threshold, 256 << 20)
    except (OSError, AttributeError):
        return


def default_workers(n_sequences: int) -> int:
    """Worker processes for ``n_sequences``: one for small sets, else one per CPU."""
    return 1 if n_sequences < POOL_MIN_SEQUENCES else max(1, os.cpu_count() or 1)


def synth_aist(
    out: str | Path,
    *,
    n_sequences: int = 24,
    full: bool = False,
    seed: int = 0,
    progress: Callable[[int, int], None] | None = None,
    overwrite: bool = False,
    workers: int | None = None,
) -> dict[str, int]:
    """Write a synthetic AIST++ dataset to ``out``; returns counts of what was written.

    ``workers`` processes write songs and batches of sequences in parallel (default: see
    :func:`default_workers`); the bytes do not depend on it."""
    from dancedata.progress import progress_bar

    out = Path(out)
    if out.exists() and any(out.iterdir()) and not overwrite:
        raise InputError("output directory exists and is not empty (use --force to replace)", out)
    plan = full_plan(seed) if full else demo_plan(n_sequences, seed)
    workers = default_workers(len(plan)) if workers is None else max(1, workers)
    tmp = out.with_name(f".{out.name}.tmp-{os.getpid()}")
    if tmp.exists():
        shutil.rmtree(tmp)
    for sub in SUBDIRS:
        (tmp / sub).mkdir(parents=True)
    try:
        settings = camera_settings(seed)
        songs = _songs(plan)
        total = len(plan) + len(songs)
        bar = progress_bar("synth aist", total=total, unit="file")
        done = 0
        tasks = list(_tasks(tmp, plan, seed, settings))
        # Worker processes pin numeric thread pools to one thread (one worker per CPU already).
        with make_executor(workers, warmups=(reuse_freed_memory,)) as executor:
            try:
                for _, n in executor.map_unordered(_run_task, tasks):
                    done += n
                    bar.update(n)
                    if progress:
                        progress(done, total)
            finally:
                bar.close()
        write_cameras(tmp, plan, settings)
        write_splits(tmp, plan, seed)
        if out.exists():
            shutil.rmtree(out)
        out.parent.mkdir(parents=True, exist_ok=True)
        os.rename(tmp, out)
    except BaseException:
        shutil.rmtree(tmp, ignore_errors=True)
        raise
    return {
        "sequences": len(plan),
        "songs": len(songs),
        "camera_settings": len({setting_of(p) for p in plan}),
    }
