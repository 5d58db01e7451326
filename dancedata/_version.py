"""dancedata's version, and the installed versions of the libraries recorded beside it."""

from __future__ import annotations

from functools import cache

__version__ = "0.1.0"


@cache
def installed_version(distribution: str) -> str | None:
    """The installed version of ``distribution`` (``importlib.metadata.version``), None when it
    is not installed. Read once per process: a look-up scans the metadata folders of
    site-packages (~0.6 ms each), and featurize asks for several per track and family (cache
    keys) besides the seven of every manifest."""
    from importlib import metadata

    try:
        return metadata.version(distribution)
    except metadata.PackageNotFoundError:
        return None
