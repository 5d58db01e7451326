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

    def message(self, command: str) -> str:
        if self.created:
            return f"{command}: wrote version {self.version}"
        return f"{command}: nothing to do, version {self.version} already holds this result"

    def as_dict(self) -> dict[str, Any]:
        return {
            "version": self.version,
            "created": self.created,
            "counts": self.counts,
            "skipped": self.skipped,
        }
