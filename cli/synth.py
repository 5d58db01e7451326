"""``dancedata synth ...``: synthetic datasets in real on-disk formats."""

from __future__ import annotations

import json
from pathlib import Path
from typing import Annotated

import typer
from dancedata.cli.apps import synth_app
from dancedata.cli.common import Json, Quiet, setup


@synth_app.command("aist")
def synth_aist_cmd(
    out: Annotated[Path, typer.Argument(help="Folder to create (AIST++ annotation layout).")],
    sequences: Annotated[
        int, typer.Option("--sequences", "-n", min=1, help="How many sequences (demo subset).")
    ] = 24,
    full: Annotated[
        bool, typer.Option("--full", help="AIST++ scale: 1408 sequences, 60 songs.")
    ] = False,
    seed: Annotated[int, typer.Option(help="Same seed, same bytes.")] = 0,
    force: Annotated[bool, typer.Option("--force", help="Replace OUT if it exists.")] = False,
    workers: Annotated[
        int | None,
        typer.Option(
            min=1,
            help="Worker processes (default: 1 for small sets, one per CPU for large ones). "
            "The output bytes do not depend on it.",
        ),
    ] = None,
    quiet: Quiet = False,
    as_json: Json = False,
) -> None:
    """Write a synthetic AIST++ dataset: motions/, keypoints3d/, keypoints2d/ (*.pkl),
    cameras/ (setting*.json, mapping.txt), splits/ (crossmodal and pose), ignore_list.txt and
    wav/m*.wav, with 4/4 music at each music id's real tempo and motion that moves with its
    measures."""
    setup(quiet)
    from dancedata.synth.aist import synth_aist

    counts = synth_aist(
        out, n_sequences=sequences, full=full, seed=seed, overwrite=force, workers=workers
    )
    if as_json:
        typer.echo(json.dumps({"command": "synth aist", "out": str(out), "counts": counts}))
    else:
        typer.echo(
            f"synth aist: wrote {counts['sequences']} sequences, {counts['songs']} songs and "
            f"{counts['camera_settings']} camera settings to {out}"
        )
