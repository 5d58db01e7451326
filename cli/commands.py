"""Imports every command module so that each registers its commands on the Typer app."""

from dancedata.cli import apps, ingest, inspect, process, synth  # noqa: F401
