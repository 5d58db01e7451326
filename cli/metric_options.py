"""The metric options of ``dancedata evaluate``, made from the metric registry.

Every field with a help text of :class:`~dancedata.study.metric_registry.ScoringSettings`
and of each registered metric's settings dataclass is one option (``--field-name``, its type,
default, lower bound and help), as :mod:`dancedata.cli.audio_options` does for the feature
families. The options are read from the registry each time the command is built, so a metric
registered after this module was imported (a plugin, a test) has its options in ``--help``.
"""

from __future__ import annotations

import functools
import inspect
from collections.abc import Callable
from typing import Any

from dancedata.cli.audio_options import settings_option, settings_values

from dancedata.featurize.family_settings import cli_settings


def metric_settings_types() -> list[type]:
    from dancedata.study.metric_registry import settings_types

    return settings_types()


class _RegistryCommand:
    """A command whose signature (hence its options) follows the metric registry."""

    def __init__(self, body: Callable[..., Any], after: str) -> None:
        functools.update_wrapper(self, body)
        self._after = after

    @property
    def __signature__(self) -> inspect.Signature:  # read by Typer when it builds the command
        body = self.__wrapped__  # type: ignore[attr-defined]
        params = []
        for param in inspect.signature(body, eval_str=True).parameters.values():
            if param.kind is inspect.Parameter.VAR_KEYWORD:
                continue
            params.append(param)
            if param.name == self._after:
                params += [
                    inspect.Parameter(
                        s.name,
                        inspect.Parameter.POSITIONAL_OR_KEYWORD,
                        default=s.default,
                        annotation=settings_option(s),
                    )
                    for cls in metric_settings_types()
                    for s in cli_settings(cls)
                ]
        return inspect.Signature(params)

    def __call__(self, *args: Any, **kwargs: Any) -> Any:
        return self.__wrapped__(*args, **kwargs)  # type: ignore[attr-defined]


def with_metric_options(after: str) -> Callable[[Callable[..., Any]], Any]:
    """Give a command the metric settings options after its parameter ``after``; the command
    takes them in ``**settings`` (read them with :func:`metric_values`)."""

    def decorate(command: Callable[..., Any]) -> Any:
        return _RegistryCommand(command, after)

    return decorate


def metric_values(values: dict[str, Any]) -> dict[str, Any]:
    """The metric settings options among a command's ``values``, by field name."""
    out: dict[str, Any] = {}
    for cls in metric_settings_types():
        out.update(settings_values(cls, values))
    return out
