"""Save and load trees of dataclasses, numpy arrays and JSON scalars without pickle.

A unit's result (e.g. one sequence read from its pickles) is split into its arrays, saved as one
.npz per unit, and a JSON description of everything else. Loading rebuilds only dataclasses
defined in the ``dancedata`` package, from their fields: nothing in the files is executed, so a
build area holds no pickles.
"""

from __future__ import annotations

import dataclasses
import importlib
from typing import Any

import numpy as np

from dancedata.errors import DancedataError, InputError


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
    raise TypeError(f"cannot save a {type(value).__name__} in a unit record")


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
