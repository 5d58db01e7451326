"""Typer sub-apps shared by the command modules (``synth``, ``ingest``, ``export``)."""

from __future__ import annotations

import typer
from dancedata.cli.main import app

synth_app = typer.Typer(
    help="Write synthetic datasets in real on-disk formats.", no_args_is_help=True
)
ingest_app = typer.Typer(help="Read a raw dataset into a new store version.", no_args_is_help=True)
export_app = typer.Typer(
    help="Write stored sequences back to interchange formats.", no_args_is_help=True
)

app.add_typer(synth_app, name="synth")
app.add_typer(ingest_app, name="ingest")
app.add_typer(export_app, name="export")
experiment_app = typer.Typer(
    help="Run experiment configs (keyframes × N × in-betweens × metrics) and render the seed "
    "tables from their results.",
    no_args_is_help=True,
)
app.add_typer(experiment_app, name="experiment")
