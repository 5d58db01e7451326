"""``dancedata info``, ``versions`` and ``validate``: read-only inspection."""

from __future__ import annotations

import json
from pathlib import Path
from typing import Annotated

import typer
from dancedata.cli.common import Json, VersionOpt
from dancedata.cli.main import app


@app.command()
def info(
    store: Annotated[Path, typer.Argument(help="Store directory.")],
    version: VersionOpt = None,
    as_json: Json = False,
) -> None:
    """Summarise a version: sequences, genres, tempi, splits, arrays and tables."""
    from dancedata.store.summary import format_info, summarize

    summary = summarize(store, version)
    typer.echo(json.dumps(summary, indent=2, default=str) if as_json else format_info(summary))


@app.command()
def versions(
    store: Annotated[Path, typer.Argument(help="Store directory.")],
    as_json: Json = False,
) -> None:
    """List committed versions, oldest first, with the command that made each."""
    from dancedata.store.layout import StoreLayout

    layout = StoreLayout(store)
    latest = layout.latest()
    rows = []
    for name in layout.committed_versions():
        manifest = layout.read_manifest(name)
        rows.append(
            {
                "version": name,
                "latest": name == latest,
                "parent": manifest.get("parent"),
                "command": manifest.get("command"),
                "created_at": manifest.get("created_at"),
                "fingerprint": manifest.get("fingerprint", "")[:12],
            }
        )
    if as_json:
        typer.echo(json.dumps(rows, indent=2))
        return
    for row in rows:
        mark = "*" if row["latest"] else " "
        typer.echo(
            f"{mark} {row['version']:<5} {row['command']:<14} parent {str(row['parent']):<5} "
            f"{row['created_at']}  {row['fingerprint']}"
        )
    leftovers = layout.temp_dirs()
    if leftovers:
        typer.echo(
            f"  ({len(leftovers)} unfinished temporary version(s) will be removed by the next "
            "writer)",
            err=True,
        )


@app.command()
def validate(
    store: Annotated[Path, typer.Argument(help="Store directory.")],
    version: VersionOpt = None,
    as_json: Json = False,
) -> None:
    """Check the store against schemas/store.schema.json; exit 1 on any contract violation."""
    from dancedata.store.validate import validate_store

    problems = validate_store(store, version)
    if as_json:
        typer.echo(json.dumps({"valid": not problems, "problems": problems}, indent=2))
    elif problems:
        for problem in problems:
            typer.echo(f"invalid: {problem}", err=True)
    else:
        typer.echo(f"valid: {store}")
    if problems:
        raise typer.Exit(code=1)
