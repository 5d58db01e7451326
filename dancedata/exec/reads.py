"""Read many input files as resumable work units, then hand the results back in order.

For commands that stream inputs into frame-concatenated arrays (``ingest aist``), where a
sequence's place in the arrays is known only after the sequences before it have been read: the
reads run first, as units of ``batch_size`` items, each saving what it read (arrays in one raw
file; the rest, and the file's index, in its marker) under the build area; then
:class:`ResumableReads` yields the items in order for the command to pack. A killed run leaves
the finished batches behind, and the next run with the same fingerprint reads only the others.
The saved reads stay until the version is committed (the build area goes then), so a run
killed while packing reads nothing again. Bad input is kept per item as the error it raised, so
``--on-error`` handling stays with the command.
"""

from __future__ import annotations

import hashlib
from collections.abc import Callable, Iterator, Sequence
from dataclasses import dataclass
from functools import partial
from typing import Any

from dancedata.errors import DancedataError
from dancedata.exec.executors import Executor, SerialExecutor
from dancedata.exec.records import decode, decode_error, encode, encode_error
from dancedata.exec.units import Job, run_units
from dancedata.store.build import BuildArea

# Items per read unit: small enough that a killed run loses little, large enough that markers
# and per-unit files stay few (AIST++: 1408 sequences → 44 units).
DEFAULT_BATCH = 32


@dataclass(frozen=True)
class ReadBatch:
    """Items [start, start + len(items)) of the input list."""

    start: int
    items: tuple[Any, ...]

    @property
    def id(self) -> str:
        digest = hashlib.sha256(repr(self.items).encode()).hexdigest()[:12]
        return f"{self.start:07d}-{digest}"


@dataclass(frozen=True)
class Loaded:
    """One item's result: the value read, or the input error it raised."""

    value: Any = None
    error: DancedataError | None = None

    def get(self) -> Any:
        if self.error is not None:
            raise self.error
        return self.value


def read_batch(
    build: BuildArea, kind: str, read: Callable[[Any], Any], batch: ReadBatch
) -> dict[str, Any]:
    """Unit function: read every item of the batch, save the arrays, describe the rest."""
    arrays: dict[str, Any] = {}
    records: list[dict[str, Any]] = []
    for k, item in enumerate(batch.items):
        try:
            records.append({"value": encode(read(item), arrays, f"i{k}_")})
        except DancedataError as exc:
            records.append({"error": encode_error(exc)})
    index = build.save_blob(f"out/{kind}/{batch.id}.bin", arrays)
    return {"records": records, "blob": index}


class ResumableReads:
    """Iterate ``read(item)`` for every item in order, reading in resumable batches.

    ``read`` must be a top-level function (picklable, for process pools) returning dataclasses,
    numpy arrays and JSON scalars; it signals bad input by raising a DancedataError.
    After iteration, ``units`` and ``resumed`` say how many batches there were and how many a
    previous run had already finished.
    """

    def __init__(
        self,
        build: BuildArea,
        kind: str,
        items: Sequence[Any],
        read: Callable[[Any], Any],
        *,
        batch_size: int | None = None,
        executor: Executor | None = None,
        desc: str = "read inputs",
    ) -> None:
        self.build = build
        self.kind = kind
        batch_size = batch_size or DEFAULT_BATCH
        self.batches = [
            ReadBatch(start, tuple(items[start : start + batch_size]))
            for start in range(0, len(items), batch_size)
        ]
        self.read = read
        self.executor = executor or SerialExecutor()
        self.desc = desc
        self.units = len(self.batches)
        self.resumed = 0

    def __iter__(self) -> Iterator[Loaded]:
        job = Job(
            self.kind,
            partial(read_batch, self.build, self.kind, self.read),
            self.desc,
            self.batches,
            "batch",
        )
        report = run_units(self.build, [job], self.executor)
        self.resumed = report.resumed
        for batch in self.batches:
            result = report.results[f"{self.kind}/{batch.id}"]
            records = result["records"]
            arrays = self.build.load_blob(f"out/{self.kind}/{batch.id}.bin", result["blob"])
            for record in records:
                if "error" in record:
                    yield Loaded(error=decode_error(record["error"]))
                else:
                    yield Loaded(value=decode(record["value"], arrays))

    def counts(self) -> dict[str, int]:
        return {"units": self.units, "resumed_units": self.resumed}
