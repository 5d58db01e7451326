"""featurize's tasks: planned on the driver, run anywhere (this process, a process pool, Dask
workers), each writing outputs no other task touches.

Motion tasks cover whole zarr chunks: task k writes output rows [frame_start, frame_stop), where
frame_start is a chunk boundary and frame_stop is the next chunk boundary after the end of a
whole sequence (or the array's end). Families need whole sequences, so a task reads every
sequence that overlaps its rows — the one sequence straddling each task boundary is computed by
both neighbours, identically, and each keeps only its own rows. Every chunk is thus written
exactly once, by one task, straight into the pre-sized array. Within a task the families run in
the job's order; an output a later family reads is handed to it in the batch, rounded to the
array's dtype (the values a later run would read from the store).

Audio tasks are tracks. Feature lengths are known only once computed, so each task saves its
arrays as .npy under the build area, and the driver packs them in track order afterwards.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from functools import lru_cache
from typing import Any

import numpy as np

from dancedata.compute.audio_features import AudioFeatureConfig
from dancedata.featurize.families.motion_base import MotionBatch
from dancedata.featurize.family import registered
from dancedata.featurize.family_settings import AudioSettings, MotionSettings
from dancedata.store.build import BuildArea
from dancedata.store.reader import _VersionReader


def open_reader(store: str, version: str, fingerprint: str) -> _VersionReader:
    """One reader per process and version: workers reuse its open arrays across tasks. The
    version's fingerprint is part of the key, so a store rebuilt under the same path and
    version name is never read through a stale reader."""
    return _cached_reader(store, version, fingerprint)


@lru_cache(maxsize=8)
def _cached_reader(store: str, version: str, fingerprint: str) -> _VersionReader:
    return _VersionReader(store, version)


# -- motion ------------------------------------------------------------------------------------
@dataclass(frozen=True)
class MotionTask:
    """Output rows [frame_start, frame_stop) of every motion array, computed from the whole
    sequences read over [read_start, read_stop); ``bounds`` are those sequences' [start, stop)
    relative to read_start."""

    frame_start: int
    frame_stop: int
    read_start: int
    read_stop: int
    bounds: tuple[tuple[int, int], ...]

    @property
    def id(self) -> str:
        return f"{self.frame_start:012d}-{self.frame_stop:012d}"


@dataclass(frozen=True)
class MotionJob:
    """What every motion task shares: where to read and write, and what to compute."""

    store: str
    parent: str
    parent_fingerprint: str
    build: BuildArea
    families: tuple[str, ...]
    settings: MotionSettings
    needed: tuple[str, ...]  # arrays read from the store, e.g. ("axis_angle",)
    # Outputs a later family of the job reads (handed over in the batch, not read back).
    handed_on: tuple[str, ...] = ()


def plan_motion_tasks(
    starts: np.ndarray, stops: np.ndarray, chunk_frames: int, target_frames: int
) -> list[MotionTask]:
    """Chunk-aligned tasks of about ``target_frames`` frames over contiguous sequences
    [starts[i], stops[i]) (frames). Each task ends on the chunk boundary at or after the end
    of the sequence holding its ``target_frames``-th frame, so a long sequence lies in one
    task and no sequence is read by more than two tasks."""
    starts = np.asarray(starts, dtype=np.int64)
    stops = np.asarray(stops, dtype=np.int64)
    total = int(stops[-1]) if len(stops) else 0
    tasks: list[MotionTask] = []
    begin = 0
    while begin < total:
        probe = min(begin + max(target_frames, 1), total) - 1
        holder = int(np.searchsorted(stops, probe, side="right"))
        end = min(total, math.ceil(int(stops[holder]) / chunk_frames) * chunk_frames)
        first = int(np.searchsorted(stops, begin, side="right"))
        last = int(np.searchsorted(stops, end - 1, side="right"))
        read_start, read_stop = int(starts[first]), int(stops[last])
        bounds = tuple(
            (int(starts[i]) - read_start, int(stops[i]) - read_start)
            for i in range(first, last + 1)
        )
        tasks.append(MotionTask(begin, end, read_start, read_stop, bounds))
        begin = end
    return tasks


def run_motion_task(job: MotionJob, task: MotionTask) -> dict[str, Any]:
    """Compute every family over the task's sequences, in the job's order, and write the
    task's rows (whole chunks) into the pre-sized arrays of the version being built."""
    reader = open_reader(job.store, job.parent, job.parent_fingerprint)
    batch = MotionBatch(
        arrays={
            name: np.asarray(
                reader.array(f"motion/{name}")[task.read_start : task.read_stop],
                dtype=np.float64,
            )
            for name in job.needed
        },
        bounds=np.asarray(task.bounds, dtype=np.int64).reshape(-1, 2),
        attrs=reader.group_attrs("motion"),
    )
    lo, hi = task.frame_start - task.read_start, task.frame_stop - task.read_start
    families = registered("motion")
    for name in job.families:
        for path, values in families[name].compute(batch, job.settings).items():
            target = job.build.open_array(f"motion/{path}")
            stored = np.asarray(values, target.dtype)
            target[task.frame_start : task.frame_stop] = stored[lo:hi]
            if path in job.handed_on:
                batch.arrays[path] = stored.astype(np.float64)
    return {"frames": hi - lo, "read_frames": task.read_stop - task.read_start}


# -- audio -------------------------------------------------------------------------------------
@dataclass(frozen=True)
class AudioTask:
    """One music track: its row in the music table and its file."""

    index: int
    music_id: str
    path: str
    bpm: float | None
    sha256: str | None = None  # of the music file, verified: the feature cache key
    span_s: float | None = None  # seconds decoded from the start (None: all of the file)
    partial: bool = False  # span_s is less than the whole track (keys the cache)

    @property
    def id(self) -> str:
        return f"{self.index:05d}-{self.music_id}"


@dataclass(frozen=True)
class AudioJob:
    build: BuildArea
    families: tuple[str, ...]
    cfg: AudioFeatureConfig
    outputs: tuple[str, ...]  # array paths relative to the audio group
    settings: AudioSettings = AudioSettings()  # stem backend, NMFD, study-family settings
    cache_dir: str | None = (
        None  # feature cache folder (dancedata.featurize.feature_cache); None: off
    )


def audio_output(task: AudioTask, path: str) -> str:
    """Build-area file of one array of one track."""
    return f"out/audio/{task.id}/{path.replace('/', '__')}.npy"


def run_audio_task(job: AudioJob, task: AudioTask) -> dict[str, Any]:
    """Every family's arrays for the track (from the feature cache, or computed on the track
    decoded once at cfg.sr; see :mod:`dancedata.featurize.audio_track`), trimmed to a common
    frame count and saved for the driver to pack."""
    from dancedata.featurize.audio_track import compute_track_features

    features, stats = compute_track_features(
        job.families,
        job.settings,
        job.cfg,
        task.path,
        task.bpm,
        audio_sha256=task.sha256,
        music_id=task.music_id,
        cache_dir=job.cache_dir,
        span_s=task.span_s,
        partial=task.partial,
    )
    n = min(features[path].shape[0] for path in job.outputs)
    for path in job.outputs:
        job.build.save_array(audio_output(task, path), np.ascontiguousarray(features[path][:n]))
    return {"frames": int(n), **stats}
