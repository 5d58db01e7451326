"""The ingest engine's reads: many inputs read as resumable tasks, handed back in order.

A sequence's place in the frame-concatenated arrays is known only after the sequences before
it have been read, so the reads run as tasks of ``batch_size`` items (on the serial,
process-pool or Dask executor), each saving what it read (arrays in one raw file; the rest, and
the file's index, in its marker) under the build area, and :class:`ResumableReads` yields the
items in order for the engine to pack: a batch as soon as it and every batch before it are
read, so a pool reads ahead while the engine packs. A killed run leaves the finished batches
behind, and the next run with the same fingerprint reads only the others. The saved reads
stay until the version is committed (the build area goes then), so a run killed while packing
reads nothing again. Bad input is kept per item as the error it raised (:class:`ReadResult`),
so ``--on-error`` handling stays with the engine.

Saved values are trees of dataclasses, numpy arrays and JSON scalars, written without pickle:
loading rebuilds only dataclasses defined in the ``dancedata`` package, from their fields, so
nothing in a build area is executed.
"""

from __future__ import annotations

import dataclasses
import hashlib
import importlib
from collections.abc import Callable, Iterator, Sequence
from dataclasses import dataclass
from functools import partial
from typing import Any

import numpy as np

from dancedata.errors import DancedataError, InputError
from dancedata.exec.executors import Executor, SerialExecutor
from dancedata.exec.tasks import Job, TaskReport, iter_tasks
from dancedata.store.build import BuildArea

# Items per read task: small enough that a killed run loses little, large enough that markers
# and per-task files stay few (AIST++: 1408 sequences → 44 tasks).
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
class ReadResult:
    """One item's read: the value, or the input error reading it raised (re-raised by
    :meth:`get`, so the engine applies ``--on-error`` in input order)."""

    value: Any = None
    error: DancedataError | None = None

    def get(self) -> Any:
        if self.error is not None:
            raise self.error
        return self.value


def read_batch(
    build: BuildArea, kind: str, read: Callable[[Any], Any], batch: ReadBatch
) -> dict[str, Any]:
    """Task function: read every item of the batch, save the arrays, describe the rest."""
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
    After iteration, ``tasks`` and ``resumed`` say how many batches there were and how many a
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
        batch_size = batch_size or DEFAULT_BATCH  # (looked up now: tests shrink it)
        self.batches = [
            ReadBatch(start, tuple(items[start : start + batch_size]))
            for start in range(0, len(items), batch_size)
        ]
        self.read = read
        self.executor = executor or SerialExecutor()
        self.desc = desc
        self.tasks = len(self.batches)
        self.resumed = 0

    def __iter__(self) -> Iterator[ReadResult]:
        job = Job(
            self.kind,
            partial(read_batch, self.build, self.kind, self.read),
            self.desc,
            self.batches,
            "batch",
        )
        report = TaskReport()
        finished = iter_tasks(self.build, [job], self.executor, report)
        for batch in self.batches:
            key = f"{self.kind}/{batch.id}"
            # Batch k is packed as soon as it is read, while a pool reads the next ones.
            while key not in report.results:
                next(finished)
            result = report.results[key]
            records = result["records"]
            arrays = self.build.load_blob(f"out/{self.kind}/{batch.id}.bin", result["blob"])
            for record in records:
                if "error" in record:
                    yield ReadResult(error=decode_error(record["error"]))
                else:
                    yield ReadResult(value=decode(record["value"], arrays))
        for _key in finished:  # (no task left: closes the progress bar)
            pass
        self.resumed = report.resumed

    def counts(self) -> dict[str, int]:
        """For the manifest counts, whose keys (``units``) are part of the store format."""
        return {"units": self.tasks, "resumed_units": self.resumed}


# ----------------------------------------------------------------------------- saving values


def encode(value: Any, arrays: dict[str, np.ndarray], prefix: str) -> Any:
    """JSON-able description of ``value``; its arrays go into ``arrays`` under ``prefix``."""
    if isinstance(value, np.ndarray):
        key = f"{prefix}{len(arrays)}"
        arrays[key] = value
        return {"__array__": key}
    if isinstance(value, np.generic):
        return value.item()
    if dataclasses.is_dataclass(value) and not isinstance(value, type):
        cls = type(value)
        return {
            "__dataclass__": f"{cls.__module__}:{cls.__qualname__}",
            "fields": {
                f.name: encode(getattr(value, f.name), arrays, prefix)
                for f in dataclasses.fields(value)
                if f.init
            },
        }
    if isinstance(value, tuple | list):
        return {
            "__seq__": type(value).__name__,
            "items": [encode(v, arrays, prefix) for v in value],
        }
    if isinstance(value, dict):
        if not all(isinstance(k, str) for k in value):
            raise TypeError("only dicts with string keys can be saved")
        return {"__dict__": {k: encode(v, arrays, prefix) for k, v in value.items()}}
    if value is None or isinstance(value, bool | int | float | str):
        return value
    raise TypeError(f"cannot save a {type(value).__name__} in a read record")


def decode(value: Any, arrays: Any) -> Any:
    """Inverse of :func:`encode`; ``arrays`` maps keys to arrays (e.g. an open .npz)."""
    if isinstance(value, dict):
        if "__array__" in value:
            return np.asarray(arrays[value["__array__"]])
        if "__dataclass__" in value:
            cls = _dataclass(value["__dataclass__"])
            return cls(**{k: decode(v, arrays) for k, v in value["fields"].items()})
        if "__seq__" in value:
            items = [decode(v, arrays) for v in value["items"]]
            return tuple(items) if value["__seq__"] == "tuple" else items
        if "__dict__" in value:
            return {k: decode(v, arrays) for k, v in value["__dict__"].items()}
    return value


def _dataclass(name: str) -> type:
    module, _, qualname = name.partition(":")
    if module != "dancedata" and not module.startswith("dancedata."):
        raise ValueError(f"refusing to rebuild {name}: not a dancedata class")
    obj: Any = importlib.import_module(module)
    for part in qualname.split("."):
        obj = getattr(obj, part)
    if not (isinstance(obj, type) and dataclasses.is_dataclass(obj)):
        raise ValueError(f"refusing to rebuild {name}: not a dataclass")
    return obj


def encode_error(exc: DancedataError) -> dict[str, Any]:
    cls = type(exc)
    return {
        "type": f"{cls.__module__}:{cls.__qualname__}",
        "problem": exc.problem,
        "path": exc.path,
    }


def decode_error(record: dict[str, Any]) -> DancedataError:
    """The saved error as its own DancedataError subclass where it can be found, else
    InputError: the same one-line message either way."""
    module, _, qualname = str(record.get("type", "")).partition(":")
    cls: Any = InputError
    if module.startswith("dancedata"):
        try:
            found: Any = importlib.import_module(module)
            for part in qualname.split("."):
                found = getattr(found, part)
            if isinstance(found, type) and issubclass(found, DancedataError):
                cls = found
        except (ImportError, AttributeError):
            pass
    error = cls.__new__(cls)
    DancedataError.__init__(error, record["problem"], record.get("path"))
    return error
