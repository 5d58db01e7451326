"""The command-line options of the ingest sources, declared as dataclass fields.

Each source folder's ``__init__.py`` holds an ``Options`` dataclass (keyword-only, a subclass
of :class:`IngestOptions`): one field per parameter of ``dancedata ingest <name>`` in --help
order, made with :func:`argument`, :func:`option` or :func:`common`, its docstring the command's
help, and :meth:`IngestOptions.run` the ingest. ``cli/ingest.py`` builds every command from
these fields (the metadata shape of :func:`dancedata.featurize.family_settings.setting`: the
field's ``metadata["cli"]``), so an option is one field and no CLI module changes.

Kept free of numpy and of the sources' code: every ``dancedata`` start-up imports the
``__init__.py`` of each source folder; the source itself lives in ``<name>/source.py``.
"""

from __future__ import annotations

import importlib
import pkgutil
from dataclasses import MISSING, field
from typing import Any, ClassVar

__all__ = ["IngestOptions", "argument", "common", "option", "source_options"]

# Options shared with other commands, their help texts in cli/common.py.
COMMON_OPTIONS = ("workers", "dask", "on_error", "wait")


def _field(default: Any, cli: dict[str, Any]) -> Any:
    return field(default=default, metadata={"cli": cli})


def argument(default: Any = MISSING, *, help: str) -> Any:  # noqa: A002 - click's name
    """A positional argument (``RAW``, ``[PATHS]...``); no default: required."""
    return _field(default, {"help": help, "argument": True})


def option(
    default: Any = MISSING,
    *,
    help: str,  # noqa: A002 - the option's help, as click names it
    flags: tuple[str, ...] = (),
    choices: tuple[str, ...] | None = None,
    min: float | None = None,  # noqa: A002 - the option's lower bound, as click names it
    metavar: str | None = None,
) -> Any:
    """An option: ``--field-name`` (or ``flags``, e.g. ``("--store", "-s")``; one ``--x`` flag
    for a bool makes it a flag without ``--no-x``), one of ``choices`` when given, at least
    ``min``; no default: required."""
    cli = {"help": help, "flags": flags, "choices": choices, "min": min, "metavar": metavar}
    return _field(default, cli)


def common(name: str, default: Any) -> Any:
    """An option every ingest command shares with other commands (``--workers``, ``--dask``,
    ``--on-error``, ``--wait``), declared once in cli/common.py."""
    if name not in COMMON_OPTIONS:
        raise ValueError(f"no common option {name!r} (known: {', '.join(COMMON_OPTIONS)})")
    return _field(default, {"common": name})


class IngestOptions:
    """Base of the sources' ``Options`` dataclasses: what the command does with its values.

    ``store`` names the store written; ``on_error`` is "fail" or "skip" (choices arrive as
    their strings). The command prints ``run()``'s result, then :meth:`notes` (``notes_err``:
    on stderr) unless ``--json``.
    """

    store: Any
    notes_err: ClassVar[bool] = True

    def run(self) -> Any:
        """Ingest into ``self.store``; the command's :class:`CommandResult`."""
        raise NotImplementedError

    def notes(self, result: Any, quiet: bool) -> list[str]:
        """Lines worth a look printed after the result line (none by default)."""
        return []


def source_options() -> dict[str, type[IngestOptions]]:
    """Each source folder's ``Options`` class, by source name (folder order): every package of
    ``dancedata.ingest`` whose ``__init__`` defines one."""
    import dancedata.ingest as package

    found: dict[str, type[IngestOptions]] = {}
    for info in pkgutil.iter_modules(package.__path__):
        if info.ispkg:
            module = importlib.import_module(f"dancedata.ingest.{info.name}")
            options = getattr(module, "Options", None)
            if isinstance(options, type) and issubclass(options, IngestOptions):
                found[info.name] = options
    return found


def ingest_into(store: Any, name: str, *inputs: Any) -> Any:
    """``ingest(store, source_named(name)(*inputs))``, leaving no empty store behind when a
    first ingest fails."""
    from dancedata.ingest.engine import ingest
    from dancedata.ingest.registry import source_named
    from dancedata.store.backend_open import make_backend
    from dancedata.store.first_write import remove_store_if_left_empty

    handle = make_backend(store)  # resolved once: the engine, the lock and the source share it
    with remove_store_if_left_empty(handle):  # a failed first ingest leaves no empty store
        return ingest(handle, source_named(name)(*inputs))


def source_exports(package: str) -> Any:
    """A source package's module ``__getattr__``: names not in its ``__init__`` come from its
    ``source`` module, imported on first use (``from dancedata.ingest.bvh import ingest_bvh``
    keeps working while start-up imports only the options)."""

    def exported(name: str) -> Any:
        if name.startswith("__"):
            raise AttributeError(name)
        module = importlib.import_module(f"{package}.source")
        try:
            return getattr(module, name)
        except AttributeError:
            raise AttributeError(f"module {package!r} has no attribute {name!r}") from None

    return exported
