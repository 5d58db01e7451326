"""The ``dancedata`` command: a thin Typer layer over the library.

Every command imports the library code it needs inside its body, so ``dancedata --help`` and
``--version`` never load zarr, librosa, numba or torch.

How a run ends (``main``):

- success: exit 0 (``validate`` exits 1 on an invalid store, ``evaluate --strict`` likewise);
- a library error (:class:`dancedata.errors.DancedataError`): one line ``error: ...`` on stderr,
  exit 1;
- a usage error (unknown option, bad value): click's message on stderr, exit 2;
- Ctrl-C (SIGINT): the line ``interrupted; run again to resume`` on stderr, exit 130. By then the
  writer has removed its temporary version (or kept it for resuming, for resumable builds) and
  released the store lock, as on any other error;
- an OSError naming a path (a component over 255 bytes, not a folder, no permission) or a file
  name that is not UTF-8: one line ``error: <path>: <problem>``, exit 1.

``main`` ends with ``SystemExit`` (so it can be called in-process); the ``dancedata`` command and
``python -m dancedata.cli`` run :func:`run`, which ends every one of these paths through
:func:`_exit` (atexit handlers, flush, ``os._exit``), so native threads alive at exit cannot turn
the exit code into SIGABRT (134).

When the command line holds ``--json``, each of these failures also prints one JSON object on
**stdout**, where the success summary would have gone, so that a caller parsing stdout always
gets JSON: ``{"error": "...", "file": "path or null", "exit_code": 1, "kind": "InputError"}``
(``kind`` is the error class, ``usage`` or ``interrupted``).
"""

from __future__ import annotations

import json
import sys
from functools import cache, partial
from typing import Annotated, Any

import typer

from dancedata._version import __version__

INTERRUPTED = "interrupted; run again to resume"
EXIT_INTERRUPTED = 130  # 128 + SIGINT, as shells report it

# ``dancedata --help`` lists commands in the order a run uses them (then any others, as
# registered), not alphabetically or by import order.
PIPELINE_ORDER = (
    "synth", "ingest", "tempo", "featurize", "segment", "stats", "resample", "keyframes",
    "validate", "info", "versions", "checkout", "unlock", "export", "plot", "render", "report",
    "card", "experiment", "evaluate", "cache",
)  # fmt: skip


class PipelineOrderGroup(typer.core.TyperGroup):
    """The root command group, listing its commands in :data:`PIPELINE_ORDER`."""

    def list_commands(self, ctx: Any) -> list[str]:
        names = list(self.commands)
        rank = {name: i for i, name in enumerate(PIPELINE_ORDER)}
        return sorted(names, key=lambda n: (rank.get(n, len(rank)), names.index(n)))


app = typer.Typer(
    name="dancedata",
    cls=PipelineOrderGroup,
    help=(
        "Turn raw music-and-dance data (AIST++, BVH, video poses) into versioned, "
        "analysis-ready Zarr + Parquet stores.\n\n"
        "Typical run:  synth aist RAW → ingest aist RAW --store S → featurize S → segment S → "
        "validate S."
    ),
    no_args_is_help=True,
    pretty_exceptions_enable=False,
    add_completion=False,
)


def _version_callback(value: bool) -> None:
    if value:
        typer.echo(f"dancedata {__version__}")
        raise typer.Exit()


@app.callback()
def _root(
    version: Annotated[
        bool,
        typer.Option(
            "--version",
            callback=_version_callback,
            is_eager=True,
            help="Print the program's version. (After a command, --version VERSION names the "
            "store version to read: v3 or 3.)",
        ),
    ] = False,
) -> None:
    """dancedata command line."""


def _register() -> None:
    from dancedata.cli import commands  # noqa: F401  (registers commands on `app`)


@cache
def build_command() -> Any:
    """The click command tree of ``app`` with plain help (see :func:`_plain_help`), built once
    per process (about 0.2 s; click makes a fresh context for every invocation, so a caller
    running several commands in one interpreter, as the tests do, reuses the tree)."""
    _register()
    command = typer.main.get_command(app)
    _plain_help(command, "")
    return command


def _plain_help(command: Any, path: str) -> None:
    """Help that reads the same in a terminal and in a log: click's plain layout (options are
    never truncated, flags show no ``<bool>`` type), each command's first sentence in the command
    lists, and the worked example of cli/examples.py at the end of every command's help."""
    from dancedata.cli.examples import EXAMPLES

    command.rich_markup_mode = None
    for param in command.params:
        # The usage line names arguments as the help texts do (STORE SEQ_ID OUT, [PATHS]...):
        # typer writes required ones as {STORE}, which reads as a placeholder to fill in.
        if getattr(param, "param_type_name", "") == "argument":
            param.get_usage_pieces = partial(_usage_pieces, param)
        # A flag declared as --no-X (e.g. --no-music) gets no --no-no-X twin.
        if getattr(param, "is_bool_flag", False) and any(
            opt.startswith("--no-no-") for opt in param.secondary_opts
        ):
            param.secondary_opts = []
    if command.help and not command.short_help:
        command.short_help = _first_sentence(command.help)
    example = EXAMPLES.get(path)
    has_own = any(line.strip().startswith("Example") for line in (command.help or "").splitlines())
    if example and not has_own and not command.epilog:
        command.epilog = f"\b\nExample:\n  {example}"
    for name, sub in getattr(command, "commands", {}).items():
        _plain_help(sub, f"{path} {name}".strip())


def _usage_pieces(param: Any, ctx: Any) -> list[str]:
    name = param.metavar or (param.name or "").upper()
    piece = name if param.required else f"[{name}]"
    return [piece + ("..." if param.nargs != 1 and not name.endswith("...") else "")]


def _first_sentence(text: str) -> str:
    flat = " ".join(text.split("\n\n")[0].split())
    end = flat.find(". ")
    return flat if end < 0 else flat[: end + 1]


def _wants_json(argv: list[str]) -> bool:
    return "--json" in argv[: argv.index("--")] if "--" in argv else "--json" in argv


def _fail(
    message: str, exit_code: int, *, as_json: bool, kind: str, file: str | None = None
) -> None:
    """Print the failure (stderr line, plus the JSON object on stdout with --json) and exit."""
    if as_json:
        record = {"error": message, "file": file, "exit_code": exit_code, "kind": kind}
        print(json.dumps(record), flush=True)
    sys.exit(exit_code)


def _exit(code: int) -> None:
    """End the process with ``code`` on every path, without interpreter teardown.

    Python's atexit handlers run and both streams are flushed, then ``os._exit``: the C/C++
    runtime's static destructors never run. Native libraries (pyarrow's thread pools, the
    jemalloc background thread, BLAS) keep threads alive to the end, and tearing their pools
    down while a thread is still joinable aborts the process with SIGABRT ("terminate called
    without an active exception", exit 134) after the command's output was printed, in a few
    runs in a hundred under CPU load. Nothing of ours needs that teardown."""
    import atexit
    import contextlib
    import os

    try:
        atexit._run_exitfuncs()
    finally:
        for stream in (sys.stdout, sys.stderr):
            with contextlib.suppress(OSError, ValueError):  # a closed pipe: nothing to say
                stream.flush()
        os._exit(code)


def run() -> None:
    """The ``dancedata`` command: :func:`exit_code`, then :func:`_exit` with it, whatever the
    path (success, error, usage, Ctrl-C, an unexpected exception's traceback)."""
    from dancedata.exec.malloc import tune_malloc
    from dancedata.exec.numba_cache import use_machine_cache

    tune_malloc()  # before any thread starts: buffers reused, not re-faulted (see the module)
    use_machine_cache()  # before numba is imported: one cache the worker slots seed from
    code = 1
    try:
        code = exit_code()
    except BaseException:  # not an Exception (GeneratorExit, ...): still a traceback and 1
        import traceback

        traceback.print_exc()
    _exit(code)


def exit_code() -> int:
    """Run :func:`main` on ``sys.argv`` and return the exit code the process ends with: 0, the
    code of a ``SystemExit``, 130 for Ctrl-C, 1 after printing an unexpected traceback. Apart
    from :func:`run` so that a caller in the same interpreter (the tests) gets the code."""
    try:
        main()
        return 0
    except SystemExit as exc:
        if exc.code is None or isinstance(exc.code, int):
            return exc.code or 0
        print(exc.code, file=sys.stderr)  # sys.exit("message"): Python prints it and exits 1
        return 1
    except KeyboardInterrupt:
        return EXIT_INTERRUPTED
    except BrokenPipeError:  # the reader of stdout went away (`| head`): nothing to say
        return 1
    except Exception:
        import traceback

        traceback.print_exc()
        return 1


def _short_path(name: object) -> str:
    """A file name for a one-line message: decoded, at most 160 characters (middle elided)."""
    import os

    text = os.fsdecode(name) if isinstance(name, str | bytes) else str(name)
    text = text.encode("utf-8", "backslashreplace").decode("utf-8")  # non-UTF-8 bytes shown
    return text if len(text) <= 160 else f"{text[:80]}…{text[-79:]}"


def _caused_by_ctrl_c(exc: BaseException) -> bool:
    """Whether a KeyboardInterrupt is in ``exc``'s chain of causes: Ctrl-C while a module's C
    extension initialises surfaces as ``ImportError: initialization failed`` raised from the
    KeyboardInterrupt, and is an interrupt all the same (130), not a crash."""
    seen: set[int] = set()
    current: BaseException | None = exc
    while current is not None and id(current) not in seen:
        if isinstance(current, KeyboardInterrupt):
            return True
        seen.add(id(current))
        current = current.__cause__ or current.__context__
    return False


def _path_problem(exc: BaseException) -> tuple[str | None, str] | None:
    """(file, problem) when ``exc`` is about a path the user gave rather than a bug: an OSError
    naming a file (a component over 255 bytes, a path that is not a folder, no permission,
    a loop of links, ...) or a file name that is not UTF-8 reaching a writer; else None."""
    if isinstance(exc, OSError) and exc.filename is not None:
        reason = exc.strerror or type(exc).__name__
        if exc.errno == 36:  # ENAMETOOLONG
            reason += " (a path component is over 255 bytes)"
        return _short_path(exc.filename), reason
    if isinstance(exc, UnicodeEncodeError) and "surrogate" in str(exc.reason):
        return None, "a file name is not valid UTF-8; rename it (e.g. convmv -t utf-8)"
    return None


def main() -> None:
    """Console entry point: see the module docstring for exit codes and error output."""
    from dancedata.errors import DancedataError

    argv = sys.argv[1:]
    as_json = _wants_json(argv)
    command = build_command()
    try:
        code = command.main(args=argv, prog_name="dancedata", standalone_mode=False)
    except DancedataError as exc:
        typer.echo(f"error: {exc}", err=True)
        _fail(exc.problem, 1, as_json=as_json, kind=type(exc).__name__, file=exc.path)
    except typer.Abort:
        # typer turns Ctrl-C into Exit(130) (below); Abort is EOF at a prompt.
        typer.echo("Aborted!", err=True)
        _fail("aborted", 1, as_json=as_json, kind="aborted")
    except typer.TyperException as exc:  # click's usage errors (typer vendors click)
        exc.show()  # type: ignore[attr-defined]
        message = exc.format_message()  # type: ignore[attr-defined]
        _fail(message, exc.exit_code, as_json=as_json, kind="usage")  # type: ignore[attr-defined]
    except Exception as exc:
        if _caused_by_ctrl_c(exc):
            typer.echo(INTERRUPTED, err=True)
            _fail(INTERRUPTED, EXIT_INTERRUPTED, as_json=as_json, kind="interrupted")
        # The storage failed under the command (an object store that cannot be reached or
        # refuses the credentials, a full disk): one line naming the endpoint, not a traceback.
        from dancedata.store.fs import storage_problem

        problem = storage_problem(exc)
        if problem is not None:
            typer.echo(f"error: {problem}", err=True)
            _fail(problem, 1, as_json=as_json, kind="StorageError")
        path_problem = _path_problem(exc)
        if path_problem is None:
            raise
        file, problem = path_problem
        typer.echo(f"error: {file}: {problem}" if file else f"error: {problem}", err=True)
        _fail(problem, 1, as_json=as_json, kind="PathError", file=file)
    else:
        # standalone_mode=False: typer returns the code of an Exit (130 for Ctrl-C), or the
        # command's return value (None).
        if code == EXIT_INTERRUPTED:
            typer.echo(INTERRUPTED, err=True)
            _fail(INTERRUPTED, EXIT_INTERRUPTED, as_json=as_json, kind="interrupted")
        sys.exit(code if isinstance(code, int) else 0)
