"""The ``dancedata`` command: a thin Typer layer over the library.

Every command imports the library code it needs inside its body, so ``dancedata --help`` and
``--version`` never load zarr, librosa, numba or torch.
"""

from __future__ import annotations

import sys
from typing import Annotated

import typer

from dancedata._version import __version__

app = typer.Typer(
    name="dancedata",
    help=(
        "Turn raw music-and-dance data (AIST++, BVH, video poses) into versioned, "
        "analysis-ready Zarr + Parquet stores.\n\n"
        "Typical run:  synth aist RAW → ingest aist RAW --store S → featurize S → segment S → "
        "validate S."
    ),
    no_args_is_help=True,
    pretty_exceptions_enable=False,
    add_completion=False,
)


def _version_callback(value: bool) -> None:
    if value:
        typer.echo(f"dancedata {__version__}")
        raise typer.Exit()


@app.callback()
def _root(
    version: Annotated[
        bool,
        typer.Option(
            "--version", callback=_version_callback, is_eager=True, help="Print the version."
        ),
    ] = False,
) -> None:
    """dancedata command line."""


def _register() -> None:
    from dancedata.cli import commands  # noqa: F401  (registers commands on `app`)


def main() -> None:
    """Console entry point: library errors become one line on stderr and exit code 1."""
    from dancedata.errors import DancedataError

    _register()
    try:
        app()
    except DancedataError as exc:
        typer.echo(f"error: {exc}", err=True)
        sys.exit(1)
