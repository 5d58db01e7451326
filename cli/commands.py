"""Imports every command module so that each registers its commands on the Typer app."""

from dancedata.cli import (  # noqa: F401
    apps,
    cache,
    card,
    checkout,
    evaluate,
    experiment,
    export_bvh,
    ingest,
    inspect,
    keyframes,
    plot,
    process,
    render,
    report,
    resample,
    stats,
    synth,
    tempo,
    unlock,
)
