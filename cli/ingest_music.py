"""``dancedata ingest music``: music alone (no motion) into a new store version."""

from __future__ import annotations

from pathlib import Path
from typing import Annotated

import typer
from dancedata.cli.apps import ingest_app
from dancedata.cli.common import Json, OnErrorOpt, Quiet, Wait, Workers, report, setup


@ingest_app.command("music")
def ingest_music_cmd(
    paths: Annotated[
        list[Path],
        typer.Argument(
            help="Audio files, or folders searched for wav/flac/ogg/mp3/...; each "
            "file becomes one sequence named after its file stem."
        ),
    ],
    store: Annotated[
        Path, typer.Option("--store", "-s", help="Store directory (created if new).")
    ] = ...,
    bpm: Annotated[
        float | None,
        typer.Option(help="Tempo of every file, beats per minute; default: estimated per file."),
    ] = None,
    genre: Annotated[str | None, typer.Option(help="Genre of the tracks (e.g. gBR).")] = None,
    fps: Annotated[
        float, typer.Option(help="Feature frame rate (featurize decodes at fps x 512 Hz).")
    ] = 60.0,
    on_error: OnErrorOpt = "fail",
    workers: Workers = 1,
    wait: Wait = False,
    quiet: Quiet = False,
    as_json: Json = False,
) -> None:
    """Ingest music without motion: featurize, segment, plot and the loaders then work on its
    tracks (audio-only items), so a model can be run on new music.

    Example:
      dancedata ingest music song.wav other.ogg --store data/stores/new-music --bpm 120
    """
    setup(quiet)
    from dancedata.ingest.music import MusicIngestOptions, ingest_music
    from dancedata.store.first_write import remove_store_if_left_empty

    options = MusicIngestOptions(
        bpm=bpm,
        genre=genre,
        fps=fps,
        on_error=str(on_error),
        wait_for_lock=wait,
        workers=workers,
    )
    with remove_store_if_left_empty(store):
        result = ingest_music(store, list(paths), options)
    report(result, "ingest music", as_json, store=str(store))
