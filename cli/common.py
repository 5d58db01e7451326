"""Options and output helpers shared by the command modules."""

from __future__ import annotations

import json
from enum import StrEnum
from typing import TYPE_CHECKING, Annotated, Any

import typer

if TYPE_CHECKING:
    from dancedata.store.backend import StoreBackend

Quiet = Annotated[bool, typer.Option("--quiet", "-q", help="No progress bars.")]
Json = Annotated[
    bool, typer.Option("--json", help="Print a machine-readable JSON summary on stdout at the end.")
]
Wait = Annotated[
    bool,
    typer.Option(
        "--wait",
        help="If another writer holds the store lock, wait for it instead of failing; the "
        "command then works from the store as that writer left it.",
    ),
]
Workers = Annotated[
    int,
    typer.Option(
        "--workers",
        "-j",
        min=1,
        help="Local worker processes for independent tasks (same bytes as 1 worker).",
    ),
]
Dask = Annotated[
    str | None,
    typer.Option(
        "--dask",
        help="Run tasks on Dask: a scheduler address (tcp://host:8786) or local:N to "
        "start N local worker processes. Needs the 'scale' extra.",
    ),
]


def store_version(value: str | None) -> str | None:
    """``--version`` of a reading command: ``v3``, ``V3`` or ``3`` all name version v3."""
    if value is None:
        return None
    text = value.strip()
    digits = text[1:] if text[:1] in ("v", "V") else text
    if not digits.isdigit() or int(digits) < 1:
        raise typer.BadParameter(f"{value!r} is not a store version; give it as v3 or 3")
    return f"v{int(digits)}"


# Long form only: -V would read as the program's version (`dancedata --version`) elsewhere.
VersionOpt = Annotated[
    str | None,
    typer.Option(
        "--version",
        metavar="VERSION",
        callback=store_version,
        help="Store version to read: v3 or 3 (default: the latest).",
    ),
]


class OnError(StrEnum):
    fail = "fail"
    skip = "skip"


OnErrorOpt = Annotated[
    OnError,
    typer.Option(
        "--on-error",
        help="fail: stop at the first bad input. skip: go on and record each skipped input "
        "with its reason in the manifest.",
    ),
]


def open_handle(store: str) -> StoreBackend:
    """The STORE argument resolved once, here at the boundary, into the handle every step
    below takes (readers, writers, locks; worker tasks get its ``locator()`` string)."""
    from dancedata.store.backend_open import make_backend

    return make_backend(store)


def setup(quiet: bool) -> None:
    from dancedata.progress import set_quiet

    set_quiet(quiet)


def report(
    result: Any, command: str, as_json: bool, store: str | StoreBackend | None = None
) -> None:
    """Print the command's result: one human line (stderr when --json) or the JSON summary.
    A result found in a version that is not the latest (``store`` given) says which version
    is the latest and how to switch to the one that holds the result."""
    hint = _switch_hint(result, store)
    if as_json:
        summary = {"command": command, **result.as_dict()}
        if hint is not None:
            summary.update(latest=result.latest, hint=hint)
        typer.echo(json.dumps(summary, indent=2, default=str))
        return
    text = result.message(command)
    if hint is not None:
        if f"latest version is {result.latest}" not in text:
            text += f"; the latest version is {result.latest}"
        text += f"; {hint}"
    typer.echo(text)
    for item in result.skipped:
        typer.echo(f"  skipped {item['path']}: {item['error']}", err=True)


def _switch_hint(result: Any, store: str | StoreBackend | None) -> str | None:
    """For a "nothing to do" result: fill in the store's latest version when the command did
    not, and the checkout command that makes the found version the latest (None if it is)."""
    if store is None or getattr(result, "created", True):
        return None
    from dancedata.store.checkout import builds_on, switch_hint
    from dancedata.store.layout import StoreLayout

    store = open_handle(store) if isinstance(store, str) else store
    if getattr(result, "latest", None) is None:
        result.latest = StoreLayout(store).latest()
    if result.latest is not None and result.latest != result.version:
        result.latest_builds_on = builds_on(store, result.latest, result.version)
    return switch_hint(store, result.version, result.latest)


def split_csv(value: str | None) -> list[str] | None:
    if value is None:
        return None
    items = [v.strip() for v in value.split(",") if v.strip()]
    return items or None
