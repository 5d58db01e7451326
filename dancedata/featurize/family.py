"""The one base of every feature family (motion and audio), and the registry featurize reads.

A family is a class decorated with ``@register_family("name")``. It declares:

* ``group``: the Zarr group its arrays live under (``motion``: one row per motion frame, indexed
  by the sequences table; ``audio``: one row per feature frame, indexed by the music table);
* ``inputs``: the arrays it reads (:class:`ArraySpec`, paths relative to the group), from the
  store or from a family that runs earlier in the same featurize run; ``optional_inputs`` the
  ones it reads when they exist;
* ``outputs``: every array it can write, as the store contract states them (row shapes with
  ``"J"`` for the skeleton's joints and None for a length set by settings); the array part of
  ``schemas/store.schema.json`` is generated from these (:mod:`dancedata.featurize.schema_arrays`);
* ``settings_type``: its settings dataclass (:mod:`dancedata.featurize.family_settings`), whose
  fields with help become ``featurize`` options;
* ``config(settings)``: every setting that changes its numbers (manifest, fingerprint, cache).

How a family computes differs by group (a batch of whole sequences, or one music track): see
:class:`~dancedata.featurize.families.motion_base.MotionFamily` and
:class:`~dancedata.featurize.families.audio_base.AudioFamily`.

Family modules are ``dancedata/featurize/families/motion*.py`` and ``audio*.py``; the
registry imports all of them on first use (:func:`registered`), so adding a family is adding its
module. :func:`run_order` orders the families of one run so that a family reading another's
output runs after it (a topological order, stable in the order asked).
"""

from __future__ import annotations

import importlib
import pkgutil
from collections.abc import Callable, Iterable
from dataclasses import dataclass
from typing import Any, ClassVar, TypeVar

from dancedata.errors import InputError

__all__ = [
    "FAMILY_MODULE_PREFIXES",
    "ArraySpec",
    "Family",
    "register_family",
    "registered",
    "run_order",
]

# Modules of dancedata.featurize.families whose names start with one of these hold families.
FAMILY_MODULE_PREFIXES: tuple[str, ...] = ("motion", "audio")
INDEX_OF_GROUP: dict[str, str] = {"motion": "sequences", "audio": "music"}


@dataclass(frozen=True)
class ArraySpec:
    """One array relative to its group (``motion`` or ``audio``).

    ``row_shape``: the shape after the frame axis; in a declaration (``Family.outputs``) an
    entry may be ``"J"`` (the skeleton's joints) or None (set by settings). ``attrs``: what the
    array's attrs hold when written. The rest states the contract of a declared array:
    ``required_attrs`` (attrs ``validate`` expects), ``extension`` (listed under
    ``extension_arrays``, not yet checked by validate), ``nan_allowed`` and ``note``
    (the schema entry's ``$comment``).
    """

    path: str
    row_shape: tuple[Any, ...]
    dtype: Any
    attrs: dict[str, Any] | None = None
    required_attrs: tuple[str, ...] = ()
    extension: bool = False
    nan_allowed: bool = False
    note: str | None = None

    def matches(self, concrete: ArraySpec, n_joints: int) -> bool:
        """``concrete`` (an array as written) fits this declaration: same path and dtype, row
        shape equal with ``"J"`` = ``n_joints`` and None any length, the required attrs set."""
        import numpy as np

        want = tuple(n_joints if d == "J" else d for d in self.row_shape)
        shape_ok = len(want) == len(concrete.row_shape) and all(
            w is None or w == c for w, c in zip(want, concrete.row_shape, strict=True)
        )
        attrs = concrete.attrs or {}
        return (
            self.path == concrete.path
            and np.dtype(self.dtype) == np.dtype(concrete.dtype)
            and shape_ok
            and all(a in attrs for a in self.required_attrs)
        )


class Family:
    """Base of every feature family; see the module docstring for what a family declares."""

    name: ClassVar[str] = ""
    group: ClassVar[str] = ""
    settings_type: ClassVar[type] = object
    inputs: ClassVar[tuple[ArraySpec, ...]] = ()
    optional_inputs: ClassVar[tuple[ArraySpec, ...]] = ()
    outputs: ClassVar[tuple[ArraySpec, ...]] = ()

    @property
    def requires(self) -> tuple[str, ...]:
        """Paths of the arrays the family cannot run without."""
        return tuple(spec.path for spec in self.inputs)

    @property
    def reads_if_present(self) -> tuple[str, ...]:
        return tuple(spec.path for spec in self.optional_inputs)

    def config(self, settings: Any = None) -> dict[str, Any]:
        return {}

    def check(self, settings: Any) -> str | None:
        """Why the family cannot run with ``settings`` (None when it can)."""
        return None


_REGISTRY: dict[str, Family] = {}
_LOADED = False
F = TypeVar("F", bound=type)


def register_family(name: str) -> Callable[[F], F]:
    """Class decorator: name the family and register one instance of it under ``name``."""

    def register(cls: F) -> F:
        if not issubclass(cls, Family) or cls.group not in INDEX_OF_GROUP:
            raise TypeError(f"{cls.__name__}: a family subclasses MotionFamily or AudioFamily")
        known = _REGISTRY.get(name)
        if known is not None and type(known).__qualname__ != cls.__qualname__:
            raise ValueError(f"two families named {name!r}: {type(known)} and {cls}")
        cls.name = name
        _REGISTRY[name] = cls()
        return cls

    return register


def _load_family_modules() -> None:
    global _LOADED
    if _LOADED:
        return
    import dancedata.featurize.families as package

    for module in sorted(pkgutil.iter_modules(package.__path__), key=lambda m: m.name):
        if module.name.startswith(FAMILY_MODULE_PREFIXES):
            importlib.import_module(f"{package.__name__}.{module.name}")
    _LOADED = True


def registered(group: str | None = None) -> dict[str, Family]:
    """Every registered family of ``group`` (None: all), by name, in registration order."""
    _load_family_modules()
    return {n: f for n, f in _REGISTRY.items() if group is None or f.group == group}


def run_order(
    families: Iterable[Family], outputs: Callable[[Family], Iterable[str]]
) -> list[Family]:
    """``families`` ordered so that each runs after every other one whose ``outputs(family)``
    (array paths) it reads; otherwise in the order given.

    Raises:
        InputError: when families read each other's outputs in a circle.
    """
    todo = list(families)
    produced = {id(f): set(outputs(f)) for f in todo}
    reads = {id(f): set(f.requires) | set(f.reads_if_present) for f in todo}
    ordered: list[Family] = []
    while todo:
        ready = next(
            (
                f
                for f in todo
                if not any(g is not f and produced[id(g)] & reads[id(f)] for g in todo)
            ),
            None,
        )
        if ready is None:
            names = ", ".join(f.name for f in todo)
            raise InputError(
                f"the families {names} read each other's arrays in a circle; run them in "
                "separate featurize runs"
            )
        ordered.append(ready)
        todo.remove(ready)
    return ordered
