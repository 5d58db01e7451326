"""``dancedata info``, ``versions`` and ``validate``: read-only inspection."""

from __future__ import annotations

import json
from typing import Annotated

import typer
from dancedata.cli.common import Json, VersionOpt, open_handle
from dancedata.cli.main import app


@app.command()
def info(
    store: Annotated[str, typer.Argument(help="Store directory or fsspec URL (s3://...).")],
    version: VersionOpt = None,
    as_json: Json = False,
) -> None:
    """Summarise a version: sequences, genres, tempi, splits, arrays and tables."""
    from dancedata.store.summary import format_info, summarize

    summary = summarize(open_handle(store), version)
    typer.echo(json.dumps(summary, indent=2, default=str) if as_json else format_info(summary))


@app.command()
def versions(
    store: Annotated[str, typer.Argument(help="Store directory or fsspec URL (s3://...).")],
    as_json: Json = False,
) -> None:
    """List committed versions, oldest first, with the command that made each."""
    from dancedata.store.layout import StoreLayout

    handle = open_handle(store)
    layout = StoreLayout(handle)
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
    from dancedata.store.validate import store_notes

    for note in store_notes(handle):  # on stderr, so --json output stays clean
        typer.echo(f"  note: {note}", err=True)
    if as_json:
        typer.echo(json.dumps(rows, indent=2))
        return
    for row in rows:
        mark = "*" if row["latest"] else " "
        typer.echo(
            f"{mark} {row['version']:<5} {row['command']:<14} parent {str(row['parent']):<5} "
            f"{row['created_at']}  {row['fingerprint']}"
        )


@app.command()
def validate(
    store: Annotated[str, typer.Argument(help="Store directory or fsspec URL (s3://...).")],
    version: VersionOpt = None,
    deep: Annotated[
        bool,
        typer.Option(
            "--deep",
            help="Also re-hash every chunk and table against the checksums recorded at commit "
            "(reads all the data).",
        ),
    ] = False,
    as_json: Json = False,
) -> None:
    """Check the store against schemas/store.schema.json; exit 1 on any contract violation.
    With --deep, name every corrupted chunk, array and table."""
    from dancedata.store.validate import MAX_SHOWN, shown_problems, store_notes, validate_store

    handle = open_handle(store)
    problems = validate_store(handle, version, deep=deep)
    notes = store_notes(handle)
    shown, hidden = shown_problems(problems)
    if as_json:
        record = {
            "valid": not problems,
            "deep": deep,
            "problems": shown,
            "problem_count": len(problems),
            "notes": notes[:MAX_SHOWN],
        }
        typer.echo(json.dumps(record, indent=2))
    else:
        for note in notes[:MAX_SHOWN]:
            typer.echo(f"note: {note}", err=True)
        if problems:
            for problem in shown:
                typer.echo(f"invalid: {problem}", err=True)
            if hidden:
                typer.echo(
                    f"invalid: ... and {hidden:,} more problems ({len(problems):,} in all; the "
                    f"first {len(shown)} are shown)",
                    err=True,
                )
            unverified = [p for p in problems if "checksums.json: missing" in p]
            if deep and unverified:
                typer.echo(
                    f"not verified (deep): {len(unverified)} version(s) of {store} have no "
                    "checksums.json, so their data could not be checked at all",
                    err=True,
                )
        else:
            typer.echo(f"valid{' (deep)' if deep else ''}: {store}")
    if problems:
        raise typer.Exit(code=1)
