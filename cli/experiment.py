"""``dancedata experiment run|table``: the experiment matrix and the seed tables
(docs/EXPERIMENTS.md §5)."""

from __future__ import annotations

import json
from pathlib import Path
from typing import Annotated

import typer
from dancedata.cli.apps import experiment_app
from dancedata.cli.common import Json, Quiet, VersionOpt, setup


def parse_generated(values: list[str]) -> dict[str, str]:
    """``ROW@N=DIR`` / ``ROW=DIR`` / ``DIR`` (a folder of ``<row_key>@<N>`` subfolders)."""
    out: dict[str, str] = {}
    for value in values:
        key, sep, folder = value.partition("=")
        if sep and "+" in key:
            out[key.strip()] = folder
        else:
            out["*"] = value
    return out


@experiment_app.command("run")
def run_command(
    config: Annotated[
        Path, typer.Argument(help="Experiment config (TOML), e.g. experiments/demo.toml.")
    ],
    store: Annotated[
        str | None, typer.Option("--store", "-s", help="Store directory (default: the config's).")
    ] = None,
    version: VersionOpt = None,
    out: Annotated[
        Path | None,
        typer.Option("--out", "-o", help="Results folder (default: results/<config id>)."),
    ] = None,
    generated: Annotated[
        list[str],
        typer.Option(
            "--generated",
            help="Trained-model outputs for class M rows: ROW_KEY@N=DIR, ROW_KEY=DIR, or DIR "
            "holding <row_key>@<N>/ subfolders; each DIR holds <seq_id>.npy (F, 75) Euler or "
            "(F, 225) FACT rows. Repeatable.",
        ),
    ] = [],  # noqa: B006
    smpl_model: Annotated[
        Path | None,
        typer.Option(
            help="SMPL model file for FID (default: metrics.smpl_model of the config, else the "
            "built-in edge_smpl_offsets skeleton)."
        ),
    ] = None,
    set_values: Annotated[
        list[str],
        typer.Option(
            "--set", help="Override a config key, e.g. --set split.eval=test. Repeatable."
        ),
    ] = [],  # noqa: B006
    quiet: Quiet = False,
    as_json: Json = False,
) -> None:
    """Run a config's rows (keyframe strategy + in-betweener) × N × metrics over its split and
    write results.parquet + results.json. Rows whose inputs are missing are skipped with
    their reason, never replaced."""
    setup(quiet)
    from dancedata.errors import InputError
    from dancedata.study.config import load_config
    from dancedata.study.runner import run_experiment

    cfg = load_config(config, set_values)
    where = store or cfg.data["store"]
    if where is None:
        raise InputError("no store: pass --store or set store = ... in the config", config)
    folder = out or Path("results") / cfg.id
    result = run_experiment(
        cfg,
        where,
        version=version,
        out_dir=folder,
        generated=parse_generated(generated),
        smpl_model=smpl_model,
    )
    record = result.record
    if as_json:
        typer.echo(json.dumps({"command": "experiment run", "out": str(folder),
                               "run_id": record["run_id"], "results": len(result.rows),
                               "skipped": record["skipped"]}, indent=2))  # fmt: skip
        return
    typer.echo(
        f"experiment {cfg.id}: {len(result.rows)} results on {record['split']} "
        f"({record['n_sequences']} sequences, {record['n_measures']} measures) of "
        f"{where} {record['store_version']}, run {record['run_id']} → {folder}"
    )
    reasons: dict[str, list[str]] = {}
    for skip in record["skipped"]:
        n = skip["n_keyframes"]
        cell = f"{skip['row_key']}" + (f"@{n}" if n else "")
        cell += f" {skip['metric']}" if skip["metric"] else ""
        reasons.setdefault(skip["reason"], []).append(cell)
    for reason, cells in reasons.items():
        shown = ", ".join(cells[:4]) + (f" and {len(cells) - 4} more" if len(cells) > 4 else "")
        typer.echo(f"  skipped {shown}: {reason}", err=True)


@experiment_app.command("table")
def table_command(
    table_id: Annotated[
        str | None,
        typer.Argument(
            help="Seed table id (4.1 … 4.13, CG-1, CG-2, CG-4), or the config id of a run in "
            "--results (renders each table its config lists); --list shows them."
        ),
    ] = None,
    results: Annotated[
        list[Path],
        typer.Option("--results", "-r", help="Results folder(s) of `experiment run`. Repeatable."),
    ] = [],  # noqa: B006
    fmt: Annotated[str, typer.Option("--format", "-f", help="md, latex or csv.")] = "md",
    compare_seed: Annotated[
        bool, typer.Option("--compare-seed", help="Each cell as: ours (seed), and Δ columns.")
    ] = False,
    list_ids: Annotated[
        bool, typer.Option("--list", help="List the table ids (and the runs in --results).")
    ] = False,
) -> None:
    """Render a seed table's layout (caption, row/column order, number format) from results;
    empty cells show "—" with the recorded reason as a footnote.

    Example: dancedata experiment table thesis-no-music --results results/thesis-no-music
    --compare-seed"""
    from dancedata.errors import InputError
    from dancedata.study.tables import (
        list_tables,
        load_results,
        render_table,
        resolve_table,
        run_tables,
    )

    runs = run_tables(list(results))
    if list_ids:
        typer.echo(list_tables(runs), nl=False)
        return
    if table_id is None:
        raise InputError("give a table id (or --list to see them)")
    if not results:
        raise InputError("--results: give the results folder of `dancedata experiment run`")
    rows, skipped = load_results(list(results))
    rendered = [
        render_table(one, rows, skipped, fmt, compare_seed) for one in resolve_table(table_id, runs)
    ]
    typer.echo("\n".join(rendered), nl=False)
