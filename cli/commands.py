"""Imports every command module so that each registers its commands on the Typer app."""

from dancedata.cli import apps  # noqa: F401
