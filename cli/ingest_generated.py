"""``dancedata ingest generated``: a model's output folder into a store shaped like a reference."""

from __future__ import annotations

from pathlib import Path
from typing import Annotated

import typer
from dancedata.cli.apps import ingest_app
from dancedata.cli.common import Json, OnErrorOpt, Quiet, Wait, Workers, report, setup


@ingest_app.command("generated")
def ingest_generated_cmd(
    folder: Annotated[
        Path,
        typer.Argument(
            help="Folder of generated motion, one <seq_id>.npy|.npz|.pkl per sequence of the "
            "reference (EDGE's <prefix>_<seq_id>.pkl too): FACT 225-d rows, smpl_poses + "
            "smpl_trans, axis_angle or quat + trans, or (F, J, 3) joint positions."
        ),
    ],
    store: Annotated[
        Path, typer.Option("--store", "-s", help="Store to write (created if new).")
    ] = ...,
    like: Annotated[
        Path,
        typer.Option(
            help="Reference store: its skeleton, frame rate, music, sequence metadata and "
            "splits are taken by seq_id."
        ),
    ] = ...,
    like_version: Annotated[
        str | None, typer.Option(help="Version of the reference store (default: latest).")
    ] = None,
    generated_fps: Annotated[
        float | None,
        typer.Option(
            help="Frame rate of the files (EDGE: 30); resampled to the reference's (decimation "
            "or SLERP). Default: the reference's."
        ),
    ] = None,
    generated_up_axis: Annotated[
        str, typer.Option(help="Up axis of the files: y (SMPL, FACT, Bailando) or z (EDGE).")
    ] = "y",
    smooth_cutoff: Annotated[
        float | None,
        typer.Option(
            help="Zero-phase Butterworth low-pass cutoff in Hz (scipy sosfiltfilt; gain 1/2 at "
            "the cutoff) of rotations (sign-continuous quaternions), translation and positions."
        ),
    ] = None,
    smooth_order: Annotated[
        int, typer.Option(help="Butterworth order per pass (effective order twice that).")
    ] = 2,
    repair_hip_flips: Annotated[
        bool,
        typer.Option(
            "--repair-hip-flips",
            help="Detect half-turn flips of the root rotation between frames and undo them "
            "(before smoothing); what is found is printed and recorded in the manifest.",
        ),
    ] = False,
    flip_threshold: Annotated[
        float, typer.Option(help="Root rotation step (degrees per frame) counted as a flip.")
    ] = 90.0,
    on_error: OnErrorOpt = "fail",
    workers: Workers = 1,
    wait: Wait = False,
    quiet: Quiet = False,
    as_json: Json = False,
) -> None:
    """Ingest a model's generated motion into a store with the reference's skeleton, frame rate
    and music, so render, plot, export bvh and evaluate (store against store) work on it. Files
    named by no sequence of the reference are refused (--on-error skip records them).

    Example:
      dancedata ingest generated out/lstm --store data/stores/lstm --like data/stores/aist
      --smooth-cutoff 6 --repair-hip-flips
    """
    setup(quiet)
    from dancedata.ingest.generated import GeneratedIngestOptions, flip_lines, ingest_generated
    from dancedata.store.first_write import remove_store_if_left_empty

    options = GeneratedIngestOptions(
        like=like,
        like_version=like_version,
        generated_fps=generated_fps,
        up_axis=generated_up_axis,
        smooth_cutoff=smooth_cutoff,
        smooth_order=smooth_order,
        repair_hip_flips=repair_hip_flips,
        flip_threshold_deg=flip_threshold,
        on_error=str(on_error),
        wait_for_lock=wait,
        workers=workers,
    )
    with remove_store_if_left_empty(store):
        result = ingest_generated(store, folder, options)
    report(result, "ingest generated", as_json, store=str(store))
    if not as_json and not quiet:
        for line in flip_lines(result):
            typer.echo(line)
