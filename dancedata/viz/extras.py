"""The optional ``viz`` extra: import its packages with one clear error when absent."""

from __future__ import annotations

import importlib
from types import ModuleType

from dancedata.errors import DancedataError

VIZ_HINT = "pip install 'dancedata[viz]'"


class MissingExtraError(DancedataError):
    """An optional extra the command needs is not installed (the CLI prints it, exit 1)."""


def require(module: str, what: str = "this command", extra: str = "viz") -> ModuleType:
    """Import ``module`` or raise :class:`MissingExtraError` naming the extra to install."""
    try:
        return importlib.import_module(module)
    except ImportError as exc:
        raise MissingExtraError(
            f"{what} needs the optional '{extra}' extra: pip install 'dancedata[{extra}]' "
            f"({module} is not importable: {exc})"
        ) from None
