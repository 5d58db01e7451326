"""``dancedata unlock``: clear a store's write lock by hand."""

from __future__ import annotations

from typing import Annotated

import typer
from dancedata.cli.main import app


@app.command()
def unlock(
    store: Annotated[str, typer.Argument(help="Store directory or fsspec URL (s3://...).")],
    force: Annotated[
        bool,
        typer.Option(
            "--force",
            help="Also remove a lock written on another host (whose writer this host cannot "
            "see) or an unreadable lock file. Use only when you know that writer is dead.",
        ),
    ] = False,
) -> None:
    """Remove a stale write lock. A lock whose writer is still running here is never removed;
    writers take over stale locks of this host by themselves, so this is mostly for locks left
    by a writer on another machine sharing the store."""
    from dancedata.store.unlock import unlock as run

    typer.echo(run(store, force=force))
