"""``dancedata ingest music``: music alone (no motion) into a new store version.

A source of the ingest engine (registered as "music"): each audio file becomes one sequence,
named after its file stem, with no motion arrays and one music row. Its ``n_frames`` is the
track's feature frames at ``--fps`` (featurize decodes at fps × 512 Hz, hop 512), so featurize
computes every audio family on it, ``segment`` cuts its measures from the tempo, and the loaders
give audio-only items: a model trained on a dance store can be run on new music.

Tempo: ``--bpm`` when given (one value for every file), else estimated per file
(``ingest.video.music.estimate_bpm``) and recorded as ``bpm_estimated``. ``--genre`` sets the
sequences' and tracks' genre.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass
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
)
from dancedata.ingest.video.music import MusicTrack, bpm_method, music_from_file
from dancedata.store.command_result import CommandResult

__all__ = ["MusicIngestOptions", "MusicSource", "ingest_music"]

COMMAND = "ingest music"
AUDIO_SUFFIXES = (".wav", ".flac", ".ogg", ".mp3", ".m4a", ".aac", ".aiff", ".aif", ".opus")


@dataclass
class MusicIngestOptions:
    """Settings of a music ingest; all but the lock and worker settings change the data."""

    bpm: float | None = None
    genre: str | None = None
    fps: float = 60.0
    on_error: str = "fail"
    wait_for_lock: bool = False
    workers: int = 1

    def check(self) -> None:
        if not (math.isfinite(self.fps) and 1 <= self.fps <= 1000):
            raise InputError(f"--fps must be a frame rate between 1 and 1000, got {self.fps}")
        if self.bpm is not None and not (math.isfinite(self.bpm) and 20 <= self.bpm <= 400):
            raise InputError(f"--bpm must be between 20 and 400 beats per minute, got {self.bpm}")

    def config(self) -> dict[str, Any]:
        return {
            "fps": self.fps,
            "bpm": self.bpm,
            "bpm_estimation": None if self.bpm is not None else bpm_method(),
            "genre": self.genre,
            "on_error": self.on_error,
        }


@dataclass(frozen=True)
class _TrackItem:
    path: str
    sha256: str
    bpm: float | None


def read_track(item: _TrackItem) -> MusicTrack:
    """Describe one file (header, tempo when not given): runs in a worker."""
    return music_from_file(Path(item.path), item.sha256, item.bpm)


def _audio_files(paths: list[Path]) -> list[Path]:
    """The files given, and the audio files found under any folder given, sorted per folder."""
    found: list[Path] = []
    for path in paths:
        if path.is_dir():
            found += sorted(
                p for p in path.rglob("*") if p.is_file() and p.suffix.lower() in AUDIO_SUFFIXES
            )
        else:
            found.append(path)
    return found


@register_source("music")
class MusicSource(Source):
    """Audio files as motion-less sequences (see the module docstring)."""

    command = COMMAND

    def __init__(self, paths: list[str | Path], options: MusicIngestOptions) -> None:
        options.check()
        self.paths = [Path(p) for p in paths]
        self.options = options
        self.on_error = options.on_error

    def plan(self, store: str | Path, checksums: InputChecksums, skips: SkipPolicy) -> IngestPlan:
        files = _audio_files(self.paths)
        if not files:
            raise InputError("no audio files given (wav, flac, ogg, mp3, ...)")
        stems: dict[str, Path] = {}
        tasks: list[ReadTask] = []
        keys: list[str] = []
        for path in files:
            try:
                if path.stem in stems:
                    raise InputError(
                        f"two files are named {path.stem!r} ({stems[path.stem]} and {path}): "
                        "sequence ids come from file stems",
                        path,
                    )
                sha = checksums.sha(path)
            except InputError as exc:
                skips.fail_or_skip(exc, path)
                continue
            stems[path.stem] = path
            tasks.append(ReadTask(str(path), _TrackItem(str(path), sha, self.options.bpm)))
            keys.append(f"music {path.stem} {sha}")
        return IngestPlan(
            config=self.options.config(),
            fingerprint_keys=keys,
            inputs=None,
            tasks=tasks,
            parse=read_track,
            task_kind="music",
            read_desc="read music",
            sequences_desc="ingest tracks",
            sequences_unit="track",
            workers=self.options.workers,
            wait_for_lock=self.options.wait_for_lock,
            empty_error=InputError("every music file was skipped; nothing to ingest"),
        )

    def read(self, task: ReadTask, parsed: Callable[[], Any]) -> SequenceRecord:
        track: MusicTrack = parsed()
        n_frames = track.feature_frames(self.options.fps)
        if n_frames < 1:
            raise InputError("the music is shorter than one feature frame", track.path)
        return SequenceRecord(
            seq_id=Path(track.path).stem,
            source="music",
            path=str(Path(track.path).resolve()),
            sha256=track.sha256,
            fps=self.options.fps,
            n_frames=n_frames,
            arrays={},
            genre=self.options.genre,
            music_key=track.path,
            bpm=track.bpm,
            bpm_estimated=track.bpm_estimated,
            item=track,
        )

    def finish(self, records: list[SequenceRecord], totals: IngestTotals) -> Finished:
        rows: list[dict[str, Any]] = []
        by_key: dict[str, dict[str, Any]] = {}
        start = 0
        for record in records:
            track: MusicTrack = record.item
            row = track.row(self.options.genre, start, self.options.fps)
            start = row["frame_stop"]
            rows.append(row)
            by_key[track.path] = row
        estimated = sum(bool(r.bpm_estimated) for r in records)
        counts = {
            "tracks": len(records),
            "bpm_estimated": estimated,
            "skipped": totals.skipped,
            **totals.read_counts,
        }
        return Finished(
            music=MusicTable(rows=rows, by_key=by_key),
            counts=counts,
            tables={"splits": []},
            attrs={"motion": {"fps": self.options.fps, "source": "music"}},  # no skeleton
        )


def ingest_music(
    store: str | Path, paths: list[str | Path], options: MusicIngestOptions
) -> CommandResult:
    """Ingest the music files (or folders of them) at ``paths`` into a new version of ``store``."""
    return ingest(store, MusicSource(paths, options))
