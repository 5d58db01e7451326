"""``dancedata checkout``: make an older committed version the latest again."""

from __future__ import annotations

import json
from typing import Annotated

import typer
from dancedata.cli.common import Json, Wait, open_handle
from dancedata.cli.main import app


@app.command()
def checkout(
    store: Annotated[str, typer.Argument(help="Store directory or fsspec URL (s3://...).")],
    version: Annotated[str, typer.Argument(help="Committed version to make the latest: v3 or 3.")],
    wait: Wait = False,
    as_json: Json = False,
) -> None:
    """Make VERSION the latest: readers read it by default and the next command that writes
    derives its new version from it (numbered past every existing version). Recorded in the
    checkout log of store.json (`dancedata info` shows it); nothing is copied or deleted.

    Example: dancedata checkout data/stores/aist-demo v3
    """
    from dancedata.store.checkout import checkout as run

    result = run(open_handle(store), version, wait=wait)
    if as_json:
        typer.echo(json.dumps(result.as_dict(), indent=2))
    else:
        typer.echo(result.message(store))
