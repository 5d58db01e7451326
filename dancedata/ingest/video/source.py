"""``dancedata ingest video``: video-derived poses, aligned to each video's clock, into a new
store version.

A source of the ingest engine (:mod:`dancedata.ingest.engine`, registered as "video"), which
owns checksums and the fingerprint, the lock, ``--on-error``, the parallel and resumable reads,
frame offsets, the sequences row, the tables and the commit. This module says what is specific
to videos:

* plan: which poses, CSV and music go with each video (:mod:`~dancedata.ingest.video.inputs`),
  and the fingerprint line of each (a pose folder hashed as one input);
* parse, one task per video, in worker processes (``workers``): clock → poses → frame check →
  track → fill gaps → resample (:mod:`~dancedata.ingest.video.poses`), and the video's own audio
  track as its music (:mod:`~dancedata.ingest.video.read`); a ``--music`` file is described
  once per run (:mod:`~dancedata.ingest.video.music`);
* read: music paired, every video checked against the first (frame rate, body model, CSV
  joints: a setting problem, never skipped), table columns, arrays and counts
  (:mod:`~dancedata.ingest.video.records`).

One new version holds only these sequences (its parent is recorded, nothing is carried over).
A bad input leaves the store exactly as it was; a killed run leaves the videos it finished
reading in the version's build area, and the next run with the same inputs and settings reads
only the others. The stored bytes do not depend on ``workers``.

Stored arrays (docs/STORE.md, "Video-derived poses"):

* ``motion/pose2d`` (F, J, 3) float32: x, y in pixels (origin top-left, y down) and the
  detector's confidence; x, y NaN and confidence 0 where missing. J = 25 (BODY_25) or 18 (COCO).
* ``motion/pose2d_mask`` (F, J) uint8: 0 missing, 1 detected, 2 gap-filled.
* ``motion/positions`` (F, K, 3) float32 metres from ``--joints-csv``, NaN where missing, and
  ``motion/positions_mask`` (F, K) uint8 with the same codes.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any

from dancedata.errors import InputError
from dancedata.ingest.engine import ingest
from dancedata.ingest.registry import register_source
from dancedata.ingest.source import (
    Finished,
    IngestPlan,
    IngestTotals,
    InputChecksums,
    MusicTable,
    ReadTask,
    SequenceRecord,
    SkipPolicy,
    Source,
    StoredArray,
)
from dancedata.ingest.video.inputs import (
    check_unique_stems,
    find_video_inputs,
    sequence_key,
    sequence_sha256,
)
from dancedata.ingest.video.music import bpm_method
from dancedata.ingest.video.poses import PoseSettings
from dancedata.ingest.video.read import VideoRead, VideoReadItem, read_video
from dancedata.ingest.video.records import (
    VideoSequence,
    check_consistent,
    motion_attrs,
    music_files,
    music_rows,
    pose_arrays,
    sequence_of,
    video_columns,
    video_counts,
)
from dancedata.progress import progress
from dancedata.store.command_result import CommandResult
from dancedata.store.layout import warn_once

__all__ = ["COMMAND", "VideoIngestOptions", "VideoSource", "ingest_video"]

COMMAND = "ingest video"
# Videos per resumable read task: one, so a killed run re-reads at most the videos in flight.
READ_BATCH_VIDEOS = 1


@dataclass
class VideoIngestOptions:
    """Every setting of a video ingest (all but ``wait_for_lock``, ``workers`` and ``dask``
    are fingerprinted).

    Attributes:
        poses: ``--poses`` folder (see :mod:`dancedata.ingest.video.inputs` for the mapping).
        joints_csv: ``--joints-csv`` file or folder of 3-d joints.
        music: ``--music`` file or folder; None: each video's audio track.
        no_music: store no music at all (ignore audio tracks).
        bpm: tempo of the music in beats per minute; None: estimate it per track.
        genre: genre label of every sequence.
        up_axis: the up axis recorded in the motion attrs ("-y": image and camera frames).
        settings: the per-video pipeline settings.
        on_error: "fail" or "skip" (skip a bad video, or a malformed pose file as a missing
            frame, and record it in the manifest).
        workers: processes reading videos; dask: a Dask scheduler address or "local:N" instead
            (neither is fingerprinted: the bytes do not depend on them).
    """

    poses: Path | None = None
    joints_csv: Path | None = None
    music: Path | None = None
    no_music: bool = False
    bpm: float | None = None
    genre: str | None = None
    up_axis: str = "-y"
    settings: PoseSettings = field(default_factory=PoseSettings)
    on_error: str = "fail"
    wait_for_lock: bool = False
    workers: int = 1
    dask: str | None = None

    def music_source(self) -> str:
        if self.no_music:
            return "none"
        return "file" if self.music is not None else "video_audio"

    def config(self) -> dict[str, Any]:
        return {
            "source": "video",
            **self.settings.config(),
            "inputs": {"poses": self.poses is not None, "joints_csv": self.joints_csv is not None},
            "music": self.music_source(),
            "audio_offset": 0,
            "bpm": self.bpm,
            "bpm_estimate": bpm_method() if self.bpm is None and not self.no_music else None,
            "genre": self.genre,
            "up_axis": self.up_axis,
            "on_error": self.on_error,
        }

    def check(self) -> None:
        if self.poses is None and self.joints_csv is None:
            raise InputError("give the poses: --poses DIR (OpenPose JSON) and/or --joints-csv")
        if self.no_music and self.music is not None:
            raise InputError("--music and --no-music exclude each other")
        if self.bpm is not None and not self.bpm > 0:
            raise InputError(f"--bpm must be positive, not {self.bpm}")
        if self.settings.fps is not None and not self.settings.fps > 0:
            raise InputError(f"--fps must be positive, not {self.settings.fps}")
        if self.settings.max_gap < 0:
            raise InputError(f"--max-gap must be 0 or more, not {self.settings.max_gap}")
        if self.workers < 1:
            raise InputError(f"--workers must be at least 1, not {self.workers}")


# ----------------------------------------------------------------------------- the source


@register_source("video")
class VideoSource(Source):
    """Videos (or their pose files alone) with their poses and music, as engine records
    (:mod:`dancedata.ingest.source`)."""

    command = COMMAND

    def __init__(self, videos: list[str | Path], options: VideoIngestOptions) -> None:
        self.videos = [Path(v) for v in videos]
        self.options = options
        self.on_error = options.on_error

    # -- before the version opens ----------------------------------------------------------
    def plan(self, store: str | Path, checksums: InputChecksums, skips: SkipPolicy) -> IngestPlan:
        options = self.options
        options.check()
        if not self.videos:  # pose files only: no audio track, music only from --music
            if options.settings.fps is None:
                raise InputError(
                    "no video, so the pose files carry no frame rate: give --fps (the video's "
                    "frame rate the poses were estimated at)",
                    options.poses or options.joints_csv,
                )
            options = replace(options, no_music=options.no_music or options.music is None)
            self.options = options
        check_unique_stems(self.videos)
        found = find_video_inputs(
            self.videos, options.poses, options.joints_csv, options.music, skips
        )
        keys = [sequence_key(checksums, i) for i in progress(found, "checksums", unit="video")]
        self.found, self.checksums, self.skips = found, checksums, skips
        audio_track = not options.no_music and options.music is None
        tasks = [
            ReadTask(
                str(inputs.video),
                VideoReadItem(
                    inputs=inputs,
                    settings=options.settings,
                    skip_bad_files=options.on_error == "skip",
                    audio_track=audio_track,
                    video_sha256=checksums.sha(inputs.video) if audio_track else None,
                    bpm=options.bpm,
                ),
            )
            for inputs in found
        ]
        self.first: VideoSequence | None = None
        self.specs: list[StoredArray] = []  # declared from the first video read
        return IngestPlan(
            config=options.config(),
            fingerprint_keys=keys,
            inputs=checksums.inputs(),  # every input is described by now
            tasks=tasks,
            parse=read_video,
            task_kind="videos",
            arrays=lambda first: self.specs,
            read_desc="read videos",
            sequences_desc="ingest videos",
            sequences_unit="video",
            batch_size=READ_BATCH_VIDEOS,
            workers=options.workers,
            dask=options.dask,
            wait_for_lock=options.wait_for_lock,
            empty_error=InputError("every video was skipped; nothing to ingest"),
        )

    def prepare(self, checksums: InputChecksums, skips: SkipPolicy) -> None:
        """Describe each ``--music`` file once (a bad one fails or skips its videos when they
        are accepted, in input order)."""
        no_music = self.options.no_music
        self.tracks = {} if no_music else music_files(self.found, self.options.bpm, checksums)

    # -- records ---------------------------------------------------------------------------
    def read(self, task: ReadTask, parsed: Callable[[], Any]) -> SequenceRecord:
        item: VideoReadItem = task.item
        read: VideoRead = parsed()
        seq = sequence_of(item.inputs, read, self.tracks)
        if self.first is None:
            self.specs = pose_arrays(seq.poses)
            self.first = seq.without_arrays()
        else:
            check_consistent(self.first, seq)  # a setting problem: never skipped
        self.skips.skipped += [{"path": p, "error": e} for p, e in seq.poses.bad_files]
        music, poses, options = seq.music, seq.poses, self.options
        if item.audio_track and read.audio is None and music is None:
            warn_once(
                f"{item.inputs.video}: the video has no audio track, so no music is stored for "
                "it (--music FILE gives it music)"
            )
        return SequenceRecord(
            seq_id=item.inputs.seq_id,
            source="video",
            path=str(item.inputs.video),
            sha256=sequence_sha256(self.checksums, item.inputs),
            fps=poses.fps,
            n_frames=poses.n_frames,
            arrays=seq.arrays(),
            genre=options.genre,
            music_key=None if music is None else str(music.path),
            bpm=music.bpm if music is not None else options.bpm,
            bpm_estimated=bool(music and music.bpm_estimated),
            columns=video_columns(seq),
            item=seq.without_arrays(),  # (written by then: memory holds one video's arrays)
        )

    def finish(self, records: list[SequenceRecord], totals: IngestTotals) -> Finished:
        sequences = _sequences(records)
        music = music_rows(sequences, self.options.genre, records[0].fps)
        assert self.first is not None  # (records were read)
        return Finished(
            music=MusicTable(rows=list(music.values()), by_key=music),
            counts={**video_counts(sequences, music, totals.skipped), **totals.read_counts},
            tables={"splits": []},
            attrs={"motion": motion_attrs(self.first.poses, self.options.up_axis)},
        )


def _sequences(records: list[SequenceRecord]) -> list[VideoSequence]:
    return [r.item for r in records]


def ingest_video(
    store: str | Path, videos: list[str | Path], options: VideoIngestOptions
) -> CommandResult:
    """Ingest ``videos`` with their poses (``options``) into a new version of ``store``."""
    return ingest(store, VideoSource(videos, options))
