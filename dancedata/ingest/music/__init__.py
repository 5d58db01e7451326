"""The music-only source: ``dancedata ingest music``'s options (:class:`Options`); the source
is :mod:`dancedata.ingest.music.source`, whose names (``MusicSource``, ``ingest_music``,
``MusicIngestOptions``) are importable from here too."""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Any

from dancedata.ingest.options import IngestOptions, argument, common, option, source_exports

__getattr__ = source_exports(__name__)


@dataclass(kw_only=True)
class Options(IngestOptions):
    """Ingest music without motion: featurize, segment, plot and the loaders then work on its
    tracks (audio-only items), so a model can be run on new music.

    Example:
      dancedata ingest music song.wav other.ogg --store data/stores/new-music --bpm 120
    """

    paths: list[Path] = argument(
        help="Audio files, or folders searched for wav/flac/ogg/mp3/...; each "
        "file becomes one sequence named after its file stem."
    )
    store: Path = option(help="Store directory (created if new).", flags=("--store", "-s"))
    bpm: float | None = option(
        None, help="Tempo of every file, beats per minute; default: estimated per file."
    )
    genre: str | None = option(None, help="Genre of the tracks (e.g. gBR).")
    fps: float = option(60.0, help="Feature frame rate (featurize decodes at fps x 512 Hz).")
    on_error: str = common("on_error", "fail")
    workers: int = common("workers", 1)
    wait: bool = common("wait", False)

    def run(self) -> Any:
        from dancedata.ingest.music.source import MusicIngestOptions
        from dancedata.ingest.options import ingest_into

        options = MusicIngestOptions(
            bpm=self.bpm,
            genre=self.genre,
            fps=self.fps,
            on_error=self.on_error,
            wait_for_lock=self.wait,
            workers=self.workers,
        )
        return ingest_into(self.store, "music", list(self.paths), options)
