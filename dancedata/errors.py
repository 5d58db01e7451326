"""Errors that carry the one line a user needs: which file, and what is wrong with it."""

from __future__ import annotations

from pathlib import Path


class DancedataError(Exception):
    """Base class: a problem the user can act on, printed as one line without a traceback."""

    def __init__(self, problem: str, path: str | Path | None = None) -> None:
        self.problem = problem
        self.path = str(path) if path is not None else None
        super().__init__(str(self))

    def __str__(self) -> str:
        return f"{self.path}: {self.problem}" if self.path else self.problem

    def __reduce__(self) -> tuple[type, tuple[str, str | None]]:
        # An error raised in a worker process (process pool or Dask) comes back to the client
        # pickled; rebuild it from (problem, path) so ``--json`` still names the file.
        return (type(self), (self.problem, self.path))


class InputError(DancedataError):
    """An input file is missing, malformed or unsafe."""


class StoreError(DancedataError):
    """A store is missing, malformed, locked, or does not hold what was asked for."""
