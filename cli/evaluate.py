"""``dancedata evaluate``: score generated motion against a store's ground truth on a split."""

from __future__ import annotations

import json
import os
from typing import Annotated, Any

import typer
from dancedata.cli.common import Json, Quiet, VersionOpt, setup, split_csv, store_version
from dancedata.cli.main import app
from dancedata.cli.metric_options import metric_values, with_metric_options


@app.command("evaluate")
@with_metric_options(after="row_key")
def evaluate_command(
    ctx: typer.Context,
    store: Annotated[str, typer.Argument(help="Store directory (ground truth).")],
    generated: Annotated[
        str,
        typer.Option(
            "--generated",
            "-g",
            help="Folder of generated motion, one <seq_id>.npy|.npz|.pkl per sequence (FACT "
            "225-d rows; smpl_poses + smpl_trans pickles; (F, 24, 3) joint positions), or "
            "another dancedata store.",
        ),
    ],
    generations: Annotated[
        str | None,
        typer.Option(
            help="Multimodality (mm_k, mm_g): a folder of generation runs, one subfolder per "
            "run (e.g. gens/0, gens/1, ...), each laid out like --generated; the runs' "
            "generations of the scored sequences are grouped by music piece.",
        ),
    ] = None,
    split: Annotated[str, typer.Option(help="Split to score (train, val, test).")] = "test",
    scheme: Annotated[str, typer.Option(help="Split scheme.")] = "crossmodal",
    exclude_genres: Annotated[
        str | None, typer.Option(help="Genres to leave out, comma-separated (e.g. gJB).")
    ] = None,
    smpl_model: Annotated[
        str | None,
        typer.Option(
            help="SMPL model file: joint positions by forward kinematics (default "
            "$DANCEDATA_SMPL_MODEL). Without it SMPL-24 stores use the built-in "
            "edge_smpl_offsets skeleton (root at trans, betas 0); recorded as config.skeleton."
        ),
    ] = None,
    out: Annotated[
        str | None,
        typer.Option(
            help="Folder for results.json and results.parquet (default results/evaluate-<run id>)."
        ),
    ] = None,
    row_key: Annotated[str, typer.Option(help="Row key recorded with every result.")] = (
        "generated"
    ),
    generated_fps: Annotated[
        float | None,
        typer.Option(
            help="Frame rate of the generated motion (EDGE: 30); resampled to the store's "
            "(decimation or SLERP). Default: the store's."
        ),
    ] = None,
    generated_up_axis: Annotated[
        str,
        typer.Option(help="Up axis of the generated motion: y (SMPL, FACT, Bailando) or z (EDGE)."),
    ] = "y",
    strict: Annotated[
        bool,
        typer.Option(help="Exit 1 (after writing the record) if any sequence was not scored."),
    ] = False,
    version: VersionOpt = None,
    generated_version: Annotated[
        str | None,
        typer.Option(
            callback=store_version, help="Version of a generated store: v3 or 3 (default: latest)."
        ),
    ] = None,
    quiet: Quiet = False,
    as_json: Json = False,
    **settings: Any,
) -> None:
    """Score generated motion against the store's ground truth on a split: MSE, FID_k, FID_g,
    diversity, the beat scores (mint, Bailando, ChoreoGraph MSD, coverage / hit / accuracy),
    FPD / FMD, EDGE's PFC and every other registered metric, each with its convention
    (docs/METRICS.md); the metric options come from the metrics' settings. Prints a table and
    writes results.json and results.parquet. Sequences that cannot be scored are listed with
    their reason (stderr and the record). Exit 0 when the record is written; 1 on a bad store,
    split or folder, when no sequence can be scored, or with --strict when any sequence was not
    scored.

    Example: dancedata evaluate data/stores/aist --generated out/ --convention bailando
    (one Bailando table row)."""
    setup(quiet)
    from pathlib import Path

    from dancedata.metrics.evaluate_conventions import convention_named
    from dancedata.study.evaluate import EvaluateOptions
    from dancedata.study.evaluate import evaluate as run
    from dancedata.study.scoring import EvaluateParams

    values = metric_values(settings)  # every metric setting, from the registry
    convention = values.pop("convention")
    if convention is not None:
        preset = convention_named(convention)
        for key, value in preset.params.items():
            source = ctx.get_parameter_source(key) if key in values else None
            given = source is not None and source.name in ("COMMANDLINE", "ENVIRONMENT")
            if not given:
                values[key] = value
        values["convention"] = preset.name
    params = EvaluateParams(**values)
    options = EvaluateOptions(
        generated=Path(generated),
        split=split,
        scheme=scheme,
        exclude_genres=split_csv(exclude_genres) or [],
        smpl_model=smpl_model or os.environ.get("DANCEDATA_SMPL_MODEL") or None,
        out=Path(out) if out else None,
        row_key=row_key,
        version=version,
        generated_version=generated_version,
        generated_fps=generated_fps,
        generated_up_axis=generated_up_axis,
        params=params,
        generations=Path(generations) if generations else None,
    )
    summary = run(store, options)
    if as_json:
        typer.echo(json.dumps({"command": "evaluate", **summary.as_dict()}, indent=2, default=str))
    else:
        typer.echo(summary.message("evaluate"))
    for item in summary.unscored_sequences:
        for reason, metrics in item["reasons"].items():
            typer.echo(f"  not scored {item['seq_id']} ({', '.join(metrics)}): {reason}", err=True)
    if strict and summary.unscored_sequences:
        raise typer.Exit(1)
