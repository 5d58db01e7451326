"""``dancedata keyframes``: keyframes per measure (docs/EXPERIMENTS.md §2) into a new version."""

from __future__ import annotations

from typing import Annotated

import typer
from dancedata.cli.common import (
    Json,
    Quiet,
    VersionOpt,
    Wait,
    open_handle,
    report,
    setup,
    split_csv,
)
from dancedata.cli.main import app


def parse_counts(values: list[str]) -> list[int]:
    """``["3,5", "9"]`` → [3, 5, 9]; one clear line for anything else."""
    from dancedata.errors import InputError

    out: list[int] = []
    for value in values:
        for item in split_csv(value) or []:
            try:
                out.append(int(item))
            except ValueError:
                raise InputError(f"--n takes whole numbers, got {item!r}") from None
    return out


def parse_weights(value: str | None, option: str) -> dict[str, float] | None:
    """``"drums=1,bass=0.5"`` → {"drums": 1.0, "bass": 0.5}; components left out weigh 0."""
    from dancedata.errors import InputError

    if value is None:
        return None
    weights: dict[str, float] = {}
    for item in split_csv(value) or []:
        name, sep, number = item.partition("=")
        try:
            if not sep:
                raise ValueError
            weights[name.strip()] = float(number)
        except ValueError:
            raise InputError(f"{option} takes name=weight pairs, got {item!r}") from None
    return weights


def complete(given: dict[str, float] | None, defaults: dict[str, float]) -> dict[str, float]:
    """The defaults when nothing is given, else every component named: the given weights and
    0 for the rest (so the manifest records all of them)."""
    if given is None:
        return dict(defaults)
    return {**{name: 0.0 for name in defaults}, **given}


@app.command("keyframes")
def keyframes_command(
    store: Annotated[str, typer.Argument(help="Store directory.")],
    strategy: Annotated[
        list[str],
        typer.Option(
            "--strategy",
            "-s",
            help="even, onset, stems, nmfd or dp (also peaks:onset, ...); repeat the option "
            "or separate with commas.",
        ),
    ] = ["even"],  # noqa: B006 (typer needs a literal default)
    n: Annotated[
        list[str],
        typer.Option("--n", help="Keyframes per measure N, comma-separated or repeated."),
    ] = ["3,5,9"],  # noqa: B006
    guard: Annotated[
        int, typer.Option(min=0, help="Peak edge guard G in frames (peaks < G or > L−1−G drop).")
    ] = 6,
    peak_source: Annotated[
        str,
        typer.Option(
            help="Peak candidates for onset: local_max (scipy find_peaks) or onset_detect "
            "(the stored librosa onset peaks)."
        ),
    ] = "local_max",
    fill: Annotated[
        str,
        typer.Option(
            help="Fill rule when a curve has too few peaks: adjacent_max_sum or top2_midpoint."
        ),
    ] = "adjacent_max_sum",  # fmt: skip
    stem_weights: Annotated[
        str | None,
        typer.Option(
            help="Stem weights for stems, e.g. drums=1,bass=1,vocals=1,other=1 "
            "(default all 1; stems left out weigh 0)."
        ),
    ] = None,  # fmt: skip
    nmfd_weights: Annotated[
        str | None,
        typer.Option(help="NMFD weights for nmfd, e.g. kick=1,snare=1,hihat=1 (default all 1)."),
    ] = None,
    normalize: Annotated[
        bool,
        typer.Option(help="Divide each stem / NMFD curve by its maximum over the sequence first."),
    ] = False,
    dp_distance: Annotated[
        str,
        typer.Option(
            help="DP segment error: vertical (default: the thesis's distance, same-frame "
            "residual of linear interpolation) or perpendicular (Roberts' code, time-value "
            "distance; docs/METRICS.md)."
        ),
    ] = "vertical",
    combine: Annotated[
        str, typer.Option(help="DP combination of segment errors: max (minimax) or sum.")
    ] = "max",
    euler_branch: Annotated[
        str,
        typer.Option(help="Euler curves the DP reads: principal (stored) or continuous."),
    ] = "principal",
    n_excludes_edges: Annotated[
        bool,
        typer.Option(
            "--n-excludes-edges",
            help="N counts interior keyframes only (N + 2 per measure); default: N includes "
            "the first and last frame.",
        ),
    ] = False,
    split: Annotated[
        str | None, typer.Option(help="Only the measures of this split (train, val, test).")
    ] = None,
    scheme: Annotated[str, typer.Option(help="Split scheme for --split.")] = "crossmodal",
    exclude_genres: Annotated[
        str | None, typer.Option(help="Genres to leave out, comma-separated (e.g. gJB).")
    ] = None,
    version: VersionOpt = None,
    wait: Wait = False,
    quiet: Quiet = False,
    as_json: Json = False,
) -> None:
    """Select keyframes in every measure with each strategy and N, and write the keyframes
    table (one row per keyframe) as a new version. The strategies, N and every parameter are
    recorded in the manifest; the same settings again write nothing."""
    setup(quiet)
    from dancedata.methods.keyframes import (
        DEFAULT_NMFD_WEIGHTS,
        DEFAULT_STEM_WEIGHTS,
        KeyframeParams,
    )
    from dancedata.study.keyframes import KeyframesOptions
    from dancedata.study.keyframes import keyframes as run

    strategies = [s for value in strategy for s in (split_csv(value) or [])]
    params = KeyframeParams(
        n_counts_edges=not n_excludes_edges,
        guard=guard,
        peak_source=peak_source,
        fill=fill,
        stem_weights=complete(parse_weights(stem_weights, "--stem-weights"), DEFAULT_STEM_WEIGHTS),
        nmfd_weights=complete(parse_weights(nmfd_weights, "--nmfd-weights"), DEFAULT_NMFD_WEIGHTS),
        normalize=normalize,
        dp_distance=dp_distance,
        combine=combine,
        euler_branch=euler_branch,
    )
    options = KeyframesOptions(
        strategies=strategies,
        n_keyframes=parse_counts(n),
        params=params,
        split=split,
        scheme=scheme,
        exclude_genres=split_csv(exclude_genres) or [],
        version=version,
        wait_for_lock=wait,
    )
    handle = open_handle(store)
    report(run(handle, options), "keyframes", as_json, store=handle)
