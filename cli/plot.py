"""``dancedata plot``: one sequence's figure (music, beats, measures, stems, NMFD, keyframes,
joint angles) saved as PNG, SVG or PDF. Needs the ``viz`` extra."""

from __future__ import annotations

from pathlib import Path
from typing import Annotated

import typer
from dancedata.cli.common import VersionOpt, split_csv
from dancedata.cli.main import app


@app.command()
def plot(
    store: Annotated[str, typer.Argument(help="Store directory or fsspec URL (s3://...).")],
    seq_id: Annotated[str, typer.Argument(help="Sequence id (sequences.seq_id).")],
    out: Annotated[Path, typer.Argument(help="Figure to write: .png, .svg or .pdf.")],
    joints: Annotated[
        str | None,
        typer.Option(
            help="Comma-separated joints of the joint-angle panel (skeleton names; default "
            "left/right knee and elbow, or the most-varying joints when the skeleton has none "
            "of them)."
        ),
    ] = None,
    width: Annotated[float, typer.Option(min=4.0, help="Figure width in inches.")] = 12.0,
    dpi: Annotated[float, typer.Option(min=20.0, help="Dots per inch (PNG).")] = 100.0,
    start: Annotated[
        int | None, typer.Option(help="First motion frame shown (default: 0).")
    ] = None,
    stop: Annotated[
        int | None, typer.Option(help="Motion frame to stop before (default: the end).")
    ] = None,
    version: VersionOpt = None,
) -> None:
    """Draw SEQ_ID of STORE to OUT: waveform, onset envelope and peaks, tracked beats, measure
    boundaries, per-stem onsets, NMFD kick/snare/hi-hat, keyframes (when the version has a
    keyframes table) and joint Euler angles, on one time axis (seconds; motion frames on top)."""
    from dancedata.viz.extras import require

    require("matplotlib", "dancedata plot")
    from dancedata.viz.plot import (
        DEFAULT_JOINTS,
        check_figure_path,
        save_figure,
        sequence_figure,
    )

    check_figure_path(out)
    chosen = tuple(split_csv(joints) or DEFAULT_JOINTS)
    fig = sequence_figure(
        store, seq_id, version=version, joints=chosen, width=width, dpi=dpi, start=start, stop=stop
    )
    typer.echo(f"plot: wrote {save_figure(fig, out)}")
