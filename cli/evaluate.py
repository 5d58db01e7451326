"""``dancedata evaluate``: score generated motion against a store's ground truth on a split."""

from __future__ import annotations

import json
import os
from typing import Annotated

import typer
from dancedata.cli.common import Json, Quiet, VersionOpt, setup, split_csv, store_version
from dancedata.cli.main import app


@app.command("evaluate")
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
    mse_space: Annotated[str, typer.Option(help="MSE space: euler75, euler72 or rotmat.")] = (
        "euler75"
    ),
    mse_wrap: Annotated[
        bool, typer.Option(help="Wrap Euler angle differences to (−π, π] in the MSE.")
    ] = False,
    mse_reduce: Annotated[
        str,
        typer.Option(
            help="MSE reduction: pooled or sequence_mean (units: sequences), or measure_mean "
            "(units: the complete measures of the measures table)."
        ),
    ] = "pooled",
    fid_unit: Annotated[
        str,
        typer.Option(
            help="FID / diversity unit: sequence (one feature vector each) or measure (each "
            "complete measure of the measures table)."
        ),
    ] = "sequence",
    fid_reference: Annotated[
        str,
        typer.Option(
            help="FID / diversity reference: paired_gt (the ground truth of the scored units), "
            "train_gt (the train split) or all_gt (every sequence, as mint's all of AIST++)."
        ),
    ] = "paired_gt",
    kinetic_mode: Annotated[
        str, typer.Option(help="Kinetic features: parity (AIST++ code) or corrected.")
    ] = "parity",
    normalize: Annotated[
        bool, typer.Option(help="z-score FID / diversity features by the ground truth's stats.")
    ] = True,
    drop_constant_ref_columns: Annotated[
        bool, typer.Option(help="Drop feature columns constant in the ground truth (FID).")
    ] = False,
    fid_eps: Annotated[
        float, typer.Option(help="ε added to covariances when sqrtm is not finite.")
    ] = 1e-6,
    bas_sigma: Annotated[float, typer.Option(help="σ (frames) of bas_mint / bas_bailando.")] = 3.0,
    beat_source: Annotated[
        str,
        typer.Option(
            help="Music beats of every beat metric: fact (audio/beats, the store's default) or "
            "bailando (audio/beats_bailando: featurize --audio-families bailando_beats)."
        ),
    ] = "fact",
    bas_beats: Annotated[
        str,
        typer.Option(
            help="Music beats bas_mint matches: motion_span (beats inside the compared frames) "
            "or whole_track_mint (also the track's beats after the last motion frame, as mint "
            "scores generated motion)."
        ),
    ] = "motion_span",
    beat_tol: Annotated[
        int, typer.Option(help="Beat coverage / hit / accuracy tolerance (frames).")
    ] = 12,
    beat_detector: Annotated[
        str, typer.Option(help="Motion beats for coverage / hit / accuracy: mint or bailando.")
    ] = "mint",
    msd_fps: Annotated[float, typer.Option(help="Frame rate of ChoreoGraph's beat MSD.")] = 20.0,
    fpd_parity: Annotated[
        str, typer.Option(help="FPD/FMD convention: spec (covariance, sliding) or transflower.")
    ] = "spec",
    fpd_aggregate: Annotated[
        str, typer.Option(help="FPD/FMD over music pieces: per_piece_mean or pooled.")
    ] = "per_piece_mean",
    max_frames: Annotated[
        int | None,
        typer.Option(
            min=3, help="Compare at most this many frames after --skip-frames (Bailando: 1200)."
        ),
    ] = None,
    feature_max_frames: Annotated[
        int | None,
        typer.Option(
            min=3,
            help="FID / diversity on each sequence's first N compared frames only; beat scores "
            "and MSE keep every frame (Bailando: 1200).",
        ),
    ] = None,
    convention: Annotated[
        str | None,
        typer.Option(
            help="A paper's evaluation preset, named in the record and the output: bailando "
            "(FID/Div on the first 1200 frames, root-relative, against all ground truth; BAS on "
            "whole sequences). Options given explicitly still win."
        ),
    ] = None,
    fid_origin: Annotated[
        str,
        typer.Option(
            help="Origin of the positions before the FID / diversity features: world (mint, "
            "AIST++ API) or first_frame_root (Bailando: each unit minus its first-frame root). "
            "Changes FID_k, not FID_g (docs/METRICS.md)."
        ),
    ] = "world",
    pfc_fps: Annotated[
        float,
        typer.Option(
            help="Frame rate PFC is computed at (EDGE: 30; every fps/pfc_fps-th frame). PFC "
            "uses per-frame foot displacements, so it changes with this rate."
        ),
    ] = 30.0,
    pfc_clip_frames: Annotated[
        int | None,
        typer.Option(
            min=3,
            help="PFC clip length in frames at --pfc-fps (EDGE's 5-s clips: 150); default: "
            "each scored sequence is one clip.",
        ),
    ] = None,
    skip_frames: Annotated[
        int, typer.Option(min=0, help="Frames to drop at the start of both (mint: 120).")
    ] = 0,
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
) -> None:
    """Score generated motion against the store's ground truth on a split: MSE, FID_k, FID_g,
    diversity, the beat scores (mint, Bailando, ChoreoGraph MSD, coverage / hit / accuracy),
    FPD / FMD and EDGE's PFC, each with its convention (docs/METRICS.md). Prints a table and
    writes results.json and results.parquet. Sequences that cannot be scored are listed with
    their reason (stderr and the record). Exit 0 when the record is written; 1 on a bad store,
    split or folder, when no sequence can be scored, or with --strict when any sequence was not
    scored.

    Example: dancedata evaluate data/stores/aist --generated out/ --convention bailando
    (one Bailando table row)."""
    setup(quiet)
    from pathlib import Path

    from dancedata.experiments.evaluate import EvaluateParams
    from dancedata.experiments.evaluate_conventions import convention_named
    from dancedata.pipeline.evaluate import EvaluateOptions
    from dancedata.pipeline.evaluate import evaluate as run

    values = dict(
        mse_space=mse_space,
        mse_wrap=mse_wrap,
        mse_reduce=mse_reduce,
        fid_unit=fid_unit,
        fid_reference=fid_reference,
        kinetic_mode=kinetic_mode,
        normalize=normalize,
        drop_constant_ref_columns=drop_constant_ref_columns,
        fid_eps=fid_eps,
        bas_sigma=bas_sigma,
        bas_beats=bas_beats,
        beat_source=beat_source,
        beat_tol=beat_tol,
        beat_detector=beat_detector,
        msd_fps=msd_fps,
        fpd_parity=fpd_parity,
        fpd_aggregate=fpd_aggregate,
        skip_frames=skip_frames,
        max_frames=max_frames,
        fid_origin=fid_origin,
        feature_max_frames=feature_max_frames,
        pfc_fps=pfc_fps,
        pfc_clip_frames=pfc_clip_frames,
    )
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
