"""What a store-changing command reports back."""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any


@dataclass
class CommandResult:
    """The version a command wrote (or found already holding its result) and its counts."""

    version: str
    created: bool
    counts: dict[str, Any] = field(default_factory=dict)
    skipped: list[dict[str, str]] = field(default_factory=list)
    # The store's latest version when the result was found (not created): the message names it
    # when it is another version, since "nothing to do" does not make that result the latest.
    latest: str | None = None
    # True when ``latest`` descends from ``version`` and still holds its result (no later run
    # of the same command): then there is nothing to switch to.
    latest_builds_on: bool = False

    def message(self, command: str) -> str:
        if self.created:
            return f"{command}: wrote version {self.version}"
        text = f"{command}: nothing to do, version {self.version} already holds this result"
        if self.latest is not None and self.latest != self.version:
            if self.latest_builds_on:
                text += f"; the latest version {self.latest} builds on it"
            else:
                text += f"; the latest version is {self.latest}"
        return text

    def as_dict(self) -> dict[str, Any]:
        return {
            "version": self.version,
            "created": self.created,
            "counts": self.counts,
            "skipped": self.skipped,
            "latest": self.version if self.created else self.latest,  # None: not looked up
            "latest_builds_on": self.latest_builds_on,
        }
