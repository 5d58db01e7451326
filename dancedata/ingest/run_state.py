"""What an ingest run gathers before it writes: skipped inputs and input checksums."""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from dancedata.errors import DancedataError, InputError
from dancedata.store.checksums import describe_input


@dataclass
class IngestRun:
    """Shared by the ingest commands. ``on_error`` is "fail" (re-raise the first bad input) or
    "skip" (record it, with its reason, for the manifest's ``skipped`` list)."""

    on_error: str
    skipped: list[dict[str, str]] = field(default_factory=list)
    described: dict[str, dict[str, Any]] = field(default_factory=dict)

    def fail_or_skip(self, exc: DancedataError, path: Path | str) -> None:
        if self.on_error != "skip":
            raise exc
        self.skipped.append({"path": str(exc.path or path), "error": exc.problem})

    def sha(self, path: Path) -> str:
        """sha256 of an input file, described once per run (path, bytes, sha256)."""
        key = str(path)
        if key not in self.described:
            if not path.is_file():
                raise InputError("no such file", path)
            self.described[key] = describe_input(path)
        return self.described[key]["sha256"]
