"""Imports every command module so that each registers its commands on the Typer app."""

from dancedata.cli import (  # noqa: F401
    apps,
    cache,
    checkout,
    evaluate,
    experiment,
    export_bvh,
    ingest,
    ingest_bvh,
    ingest_music,
    ingest_video,
    inspect,
    keyframes,
    plot,
    process,
    render,
    report,
    stats,
    synth,
    tempo,
    unlock,
)
