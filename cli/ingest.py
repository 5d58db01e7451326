"""``dancedata ingest <source>``: one command per ingest source, built from its options dataclass.

Every source folder ``dancedata/ingest/<name>/`` declares its command in ``Options``
(:mod:`dancedata.ingest.options`): each field one argument or option (name, type, default,
help, flags, choices, lower bound), the docstring the help. This module turns each into a Typer
command, as :mod:`dancedata.cli.audio_options` does for the feature families' settings, so a
new source or option needs no edit here.
"""

from __future__ import annotations

import inspect
from dataclasses import MISSING, Field, fields
from enum import Enum, StrEnum
from typing import Annotated, Any, get_type_hints

import typer
from dancedata.cli.apps import ingest_app
from dancedata.cli.common import Dask, Json, OnErrorOpt, Quiet, Wait, Workers, report, setup

from dancedata.ingest.options import IngestOptions, source_options

_COMMON: dict[str, Any] = {"workers": Workers, "dask": Dask, "on_error": OnErrorOpt, "wait": Wait}


def _parameter(cls: type, item: Field[Any], hint: Any) -> inspect.Parameter:
    """The Typer parameter of one options field (choices become an enum of their strings)."""
    cli = item.metadata["cli"]
    default = inspect.Parameter.empty if item.default is MISSING else item.default
    if "common" in cli:
        annotation = _COMMON[cli["common"]]
        if cli["common"] == "on_error":
            default = annotation.__origin__(default)
    else:
        kind = hint
        if cli.get("choices"):
            choices = StrEnum(  # type: ignore[misc]
                f"{cls.__module__.split('.')[-1].title()}{item.name.title()}",
                {choice: choice for choice in cli["choices"]},
            )
            optional = default is None or type(None) in getattr(hint, "__args__", ())
            kind = choices | None if optional else choices
            default = default if default in (None, inspect.Parameter.empty) else choices(default)
        if cli.get("argument"):
            info = typer.Argument(help=cli["help"])
        else:
            extra = {k: cli[k] for k in ("min", "metavar") if cli.get(k) is not None}
            info = typer.Option(*cli["flags"], help=cli["help"], **extra)
        annotation = Annotated[kind, info]
    return inspect.Parameter(
        item.name, inspect.Parameter.KEYWORD_ONLY, default=default, annotation=annotation
    )


def _command(name: str, cls: type[IngestOptions]) -> Any:
    """The ``ingest <name>`` command of an options class: its fields, then --quiet and --json."""

    def command(**values: Any) -> None:
        quiet, as_json = values.pop("quiet"), values.pop("as_json")
        setup(quiet)
        options = cls(**{k: v.value if isinstance(v, Enum) else v for k, v in values.items()})
        result = options.run()
        report(result, f"ingest {name}", as_json, store=str(options.store))
        if not as_json:
            for line in options.notes(result, quiet):
                typer.echo(line, err=options.notes_err)

    hints = get_type_hints(cls)
    params = [_parameter(cls, item, hints[item.name]) for item in fields(cls)]  # type: ignore[arg-type]
    keyword = inspect.Parameter.KEYWORD_ONLY
    params += [
        inspect.Parameter("quiet", keyword, default=False, annotation=Quiet),
        inspect.Parameter("as_json", keyword, default=False, annotation=Json),
    ]
    command.__signature__ = inspect.Signature(params)  # type: ignore[attr-defined]
    command.__doc__ = cls.__doc__
    command.__name__ = command.__qualname__ = f"ingest_{name}_cmd"
    return command


for _name, _options in source_options().items():
    ingest_app.command(_name)(_command(_name, _options))
