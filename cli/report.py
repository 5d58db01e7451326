"""``dancedata report``: the store's dataset card as one self-contained HTML page. Needs the
``viz`` extra."""

from __future__ import annotations

from pathlib import Path
from typing import Annotated

import typer
from dancedata.cli.common import VersionOpt, open_handle
from dancedata.cli.main import app


@app.command()
def report(
    store: Annotated[str, typer.Argument(help="Store directory or fsspec URL (s3://...).")],
    out: Annotated[Path, typer.Argument(help="HTML page to write.")],
    gallery: Annotated[
        int, typer.Option(min=0, help="Sequences drawn in the plot gallery (0 for none).")
    ] = 3,
    version: VersionOpt = None,
    croissant: Annotated[
        bool,
        typer.Option(
            "--croissant",
            help="Also write OUT's Croissant record (OUT with .croissant.json) and link it.",
        ),
    ] = False,
) -> None:
    """Write OUT.html: version lineage (commands, fingerprints), counts per split, genre,
    tempo, dancer and source, durations, skipped inputs, feature distributions with NaN and
    out-of-range checks, and a small gallery of sequence plots. No network: CSS and images are
    inline."""
    from dancedata.viz.extras import require

    require("matplotlib", "dancedata report")
    from dancedata.viz.report import build_report, check_report_path, write_report

    check_report_path(out)
    record = out.with_suffix(".croissant.json") if croissant else None
    handle = open_handle(store)  # one handle for the card and its Croissant record
    html = build_report(handle, version, gallery=gallery, croissant=record.name if record else None)
    if record is not None:
        from dancedata.viz.croissant import croissant_record, write_croissant

        typer.echo(
            f"report: wrote {write_croissant(croissant_record(handle, version), record, store)}"
        )
    typer.echo(f"report: wrote {write_report(html, out)} ({len(html.encode()) / 1e6:.2f} MB)")
