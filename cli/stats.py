"""``dancedata stats``: normalisation statistics of a training split into a new version."""

from __future__ import annotations

from typing import Annotated

import typer
from dancedata.cli.common import (
    Json,
    Quiet,
    VersionOpt,
    Wait,
    open_handle,
    report,
    setup,
    split_csv,
)
from dancedata.cli.main import app


@app.command("stats")
def stats_command(
    store: Annotated[str, typer.Argument(help="Store directory or URL.")],
    arrays: Annotated[
        str | None,
        typer.Option(
            help="Arrays, comma-separated (motion/quat,audio/mfcc,...). Default: the motion "
            "representations, trans, positions and the FACT audio curves the version has."
        ),
    ] = None,
    split: Annotated[str, typer.Option(help="The split the statistics describe.")] = "train",
    scheme: Annotated[str, typer.Option(help="Split scheme.")] = "crossmodal",
    version: VersionOpt = None,
    wait: Wait = False,
    quiet: Quiet = False,
    as_json: Json = False,
) -> None:
    """Compute the mean and standard deviation of every column of each array over the frames
    of one split, and store them (the normalization table) in a new version, so training
    normalises with the same numbers and exports can undo it.

    Example:
      dancedata stats data/stores/aist-demo --arrays motion/quat,audio/mfcc --split train
    """
    setup(quiet)
    from dancedata.featurize.stats import StatsOptions
    from dancedata.featurize.stats import stats as run

    options = StatsOptions(
        arrays=split_csv(arrays) or [],
        split=split,
        scheme=scheme,
        version=version,
        wait_for_lock=wait,
    )
    handle = open_handle(store)
    report(run(handle, options), "stats", as_json, store=handle)
