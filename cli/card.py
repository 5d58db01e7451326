"""``dancedata card``: a Croissant JSON-LD record (MLCommons dataset metadata) of a version."""

from __future__ import annotations

import json
from pathlib import Path
from typing import Annotated

import typer
from dancedata.cli.common import Json, VersionOpt
from dancedata.cli.main import app


@app.command()
def card(
    store: Annotated[str, typer.Argument(help="Store directory or fsspec URL (s3://...).")],
    out: Annotated[
        Path | None, typer.Option("--out", help="JSON file to write (default: print it).")
    ] = None,
    license: Annotated[
        str | None, typer.Option("--license", help="Licence of the data, e.g. CC-BY-4.0 or a URL.")
    ] = None,
    citation: Annotated[
        str | None, typer.Option("--citation", help="How to cite it (e.g. a BibTeX entry).")
    ] = None,
    name: Annotated[
        str | None, typer.Option(help="Dataset name (default: the store's folder).")
    ] = None,
    base_url: Annotated[
        str | None,
        typer.Option(
            "--base-url",
            help="Where the version's files will be published; file addresses are made "
            "relative to it (default: relative to the version folder, versions/vN/).",
        ),
    ] = None,
    version: VersionOpt = None,
    as_json: Json = False,
) -> None:
    """Write the Croissant 1.0 record of a version: its files with sha256 (tables,
    checksums.json, the Zarr arrays as a file set), record sets for the sequences, measures and
    splits tables and for the Zarr arrays (shape, dtype, chunks, units), the licence and
    citation you give, the splits, the fingerprint and the dancedata version. Nothing is written
    into the store.

    Example: dancedata card data/stores/aist-demo --out aist-demo.croissant.json --license CC-BY-4.0
    """
    from dancedata.viz.croissant import croissant_record, write_croissant

    record = croissant_record(
        store, version, license=license, citation=citation, name=name, base_url=base_url
    )
    if out is None:
        typer.echo(json.dumps(record, indent=2))
    elif as_json:
        typer.echo(json.dumps({"wrote": str(write_croissant(record, out, store))}))
    else:
        typer.echo(f"card: wrote {write_croissant(record, out, store)}")
