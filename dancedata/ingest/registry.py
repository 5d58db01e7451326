"""Ingest sources by name: ``@register_source("bvh")`` on a :class:`~dancedata.ingest.source.Source`
subclass, :func:`source_named` to find one.

A source named ``x`` lives in ``dancedata.ingest.x.source`` (its folder's ``__init__`` holds only
its command-line options) and is imported on first use, so the registry lists no module;
sources outside the package register through the ``dancedata.ingest_sources`` entry-point group
(``name = "package.module:SourceClass"``).
"""

from __future__ import annotations

import importlib
from collections.abc import Callable
from importlib.metadata import entry_points
from typing import TypeVar

from dancedata.errors import InputError
from dancedata.ingest.source import Source

__all__ = ["ENTRY_POINT_GROUP", "register_source", "registered_sources", "source_named"]

ENTRY_POINT_GROUP = "dancedata.ingest_sources"
_SOURCES: dict[str, type[Source]] = {}
S = TypeVar("S", bound=type[Source])


def register_source(name: str) -> Callable[[S], S]:
    """Class decorator: register a source under ``name`` (sets its ``name``)."""

    def register(cls: S) -> S:
        known = _SOURCES.get(name)
        if known is not None and known.__qualname__ != cls.__qualname__:
            raise ValueError(f"ingest source {name!r} is already registered by {known}")
        cls.name = name
        _SOURCES[name] = cls
        return cls

    return register


def source_named(name: str) -> type[Source]:
    """The source class registered as ``name``: importing ``dancedata.ingest.<name>.source`` or an
    entry point of that name first when needed. InputError for an unknown name."""
    if name not in _SOURCES and name.isidentifier():
        try:
            importlib.import_module(f"dancedata.ingest.{name}.source")
        except ModuleNotFoundError as exc:
            if exc.name not in (f"dancedata.ingest.{name}", f"dancedata.ingest.{name}.source"):
                raise
    if name not in _SOURCES:
        for point in entry_points(group=ENTRY_POINT_GROUP, name=name):
            point.load()
    if name not in _SOURCES:
        known = ", ".join(sorted(_SOURCES)) or "none imported yet"
        raise InputError(f"unknown ingest source {name!r} (registered: {known})")
    return _SOURCES[name]


def registered_sources() -> dict[str, type[Source]]:
    """Sources registered so far (those imported), by name."""
    return dict(_SOURCES)
