"""Options of ``dancedata featurize`` that choose and configure the feature families.

The families' settings options are not written here: :func:`with_settings_options` makes one
option per field of a settings dataclass that carries a help text
(:mod:`dancedata.featurize.family_settings`), with the field's name, type, default and lower
bound, so a new setting reaches the command line without an edit here.
"""

from __future__ import annotations

import inspect
from collections.abc import Callable
from pathlib import Path
from typing import Annotated, Any

import typer

from dancedata.featurize.family_settings import CliSetting, cli_settings

_TYPES: dict[str, type] = {"str": str, "int": int, "float": float, "bool": bool, "path": Path}


def settings_option(setting: CliSetting) -> Any:
    """The Typer annotation of one settings field's option."""
    kind: Any = _TYPES[setting.kind]
    if setting.optional:
        kind = kind | None
    extra = {} if setting.min is None else {"min": setting.min}
    return Annotated[kind, typer.Option(help=setting.help, **extra)]


def with_settings_options(after: dict[str, type]) -> Callable[[Callable[..., Any]], Any]:
    """Give a command the options of settings dataclasses: ``after`` maps a parameter of the
    command to the dataclass whose options follow it. The command takes them in ``**settings``
    (read them with :func:`settings_values`)."""

    def decorate(command: Callable[..., Any]) -> Callable[..., Any]:
        params = []
        for param in inspect.signature(command, eval_str=True).parameters.values():
            if param.kind is inspect.Parameter.VAR_KEYWORD:
                continue
            params.append(param)
            if param.name in after:
                params += [
                    inspect.Parameter(
                        s.name,
                        inspect.Parameter.POSITIONAL_OR_KEYWORD,
                        default=s.default,
                        annotation=settings_option(s),
                    )
                    for s in cli_settings(after[param.name])
                ]
        command.__signature__ = inspect.Signature(params)  # type: ignore[attr-defined]
        return command

    return decorate


def settings_values(cls: type, values: dict[str, Any]) -> dict[str, Any]:
    """The options of dataclass ``cls`` among ``values``, paths made absolute strings."""
    out = {}
    for setting in cli_settings(cls):
        value = values[setting.name]
        if setting.kind == "path" and value is not None:
            value = str(Path(value).resolve())
        out[setting.name] = value
    return out


AudioFamilies = Annotated[
    str | None,
    typer.Option(
        help="Audio feature families, comma-separated. Default set: fact (onset_env, mfcc, "
        "chroma_cens, onset_peaks, beats), stems (onset_env, mfcc, onset_peaks of each of "
        "drums, bass, vocals, other under audio/stems/<stem>/), nmfd (audio/nmfd_drums (A, 3): "
        "kick, snare, hi-hat NMFD activations of the drums stem). On request: mel96 (96-bin "
        "log-power mel at the motion frame rate, ChoreoGraph), stft_frames (per-motion-frame "
        "STFT: --stft-sr Hz, one chunk per frame, hop 200, n_fft 2048 → (A, 1025, k), k = 2 at "
        "60 fps and 16 kHz), tempogram (autocorrelation tempogram, --tempogram-frames lags), "
        "bailando_beats (audio/beats_bailando: Bailando's music beats). "
        "Default: fact,stems,nmfd (fact alone with --stems none).",
    ),
]
CacheDir = Annotated[
    Path | None,
    typer.Option(
        help="Feature cache folder (per-track audio features by content). Default: "
        "$DANCEDATA_CACHE, else ~/.cache/dancedata/features.",
    ),
]
UseCache = Annotated[
    bool,
    typer.Option(
        "--cache/--no-cache",
        help="Reuse and save per-track audio features in the feature cache.",
    ),
]
AcceptChangedMusic = Annotated[
    bool,
    typer.Option(
        "--accept-changed-music",
        help="Use music files that changed since ingest as they are now: re-hash them and "
        "record the new sha256, size, mtime and header in the new version's music table (and "
        "the new hashes in its config). Without it a changed file stops featurize with a line "
        "naming it.",
    ),
]
MaxAudioSeconds = Annotated[
    float,
    typer.Option(
        min=0,
        help="Most seconds of one track to decode (the span its sequences need plus 30 s, or "
        "the whole track when shorter). A track needing more is refused before decoding; 0: "
        "no limit. With the default families 10 decoded minutes peak at 2.5 GB per worker.",
    ),
]
