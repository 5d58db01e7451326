"""``dancedata resample``: a store version at another motion frame rate, as a new version."""

from __future__ import annotations

from typing import Annotated

import typer
from dancedata.cli.common import Json, Quiet, VersionOpt, Wait, open_handle, report, setup
from dancedata.cli.main import app


@app.command("resample")
def resample_command(
    store: Annotated[str, typer.Argument(help="Store directory or URL.")],
    fps: Annotated[
        str,
        typer.Option(
            "--fps",
            metavar="FPS",
            help="Target motion frame rate, frames per second: a finite number in (0, 1000]. "
            "Any ratio to the store's rate works; an integer ratio (60 → 20) keeps every k-th "
            "frame exactly.",
        ),
    ],
    featurize: Annotated[
        bool,
        typer.Option(
            help="Recompute the version's audio features (and windowed motion features) at "
            "the new rate with featurize, as the next version.",
        ),
    ] = True,
    version: VersionOpt = None,
    wait: Wait = False,
    quiet: Quiet = False,
    as_json: Json = False,
) -> None:
    """Resample a version's motion to another frame rate into a new version: rotations by
    SLERP, positions and translations linearly, motion beats to the nearest frame; frames at
    i / FPS seconds inside each sequence, n_out = floor((n_in - 1) * FPS / fps_in) + 1.
    Audio features keep one row per motion frame (sr = FPS x 512), so they are recomputed by
    featurize at the new rate; measures, beats and phrases are recomputed on the tempo grid.
    The manifest records the resampler, the source and the target fps.

    Example:
      dancedata resample data/stores/aist-demo --fps 20
    """
    setup(quiet)
    from dancedata.featurize.resample_store import ResampleOptions, check_fps
    from dancedata.featurize.resample_store import resample as run

    options = ResampleOptions(
        fps=check_fps(fps), version=version, wait_for_lock=wait, featurize=featurize
    )
    handle = open_handle(store)
    report(run(handle, options), "resample", as_json, store=handle)
