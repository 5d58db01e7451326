"""``dancedata ingest bvh``: BVH files (any rig, any channel order) into a new store version."""

from __future__ import annotations

from pathlib import Path
from typing import Annotated

import typer
from dancedata.cli.apps import ingest_app
from dancedata.cli.common import (
    Dask,
    Json,
    OnError,
    OnErrorOpt,
    Quiet,
    Wait,
    Workers,
    report,
    setup,
)


@ingest_app.command("bvh")
def ingest_bvh_cmd(
    paths: Annotated[
        list[Path] | None,
        typer.Argument(
            help="BVH files or folders (searched recursively for --glob); each file becomes "
            "one sequence named after its file stem. May be left out when --manifest lists the "
            "files."
        ),
    ] = None,
    store: Annotated[
        Path, typer.Option("--store", "-s", help="Store directory (created if new).")
    ] = ...,
    units: Annotated[
        str,
        typer.Option(
            help="Length unit of the files: m, cm, mm, in, ft, dm, or metres per unit as a "
            "number (CMU cgspeed BVH: 0.056444). Stored lengths are metres."
        ),
    ] = "cm",
    size_check: Annotated[
        bool,
        typer.Option(help="Refuse rigs smaller than 0.3 m or larger than 3 m (a wrong --units)."),
    ] = True,
    fps: Annotated[
        float | None,
        typer.Option(
            help="Resample to this frame rate: every k-th frame for an integer ratio, "
            "SLERP otherwise. Default: the files' own rate (all files must share it)."
        ),
    ] = None,
    smooth_cutoff: Annotated[
        float | None,
        typer.Option(
            help="Low-pass joint rotations at this cut-off (Hz): zero-phase Butterworth on "
            "sign-continuous quaternions, before resampling."
        ),
    ] = None,
    smooth_order: Annotated[int, typer.Option(min=1, help="Butterworth order.")] = 2,
    music: Annotated[
        Path | None, typer.Option(help="Music of the (single) BVH file; featurize analyses it.")
    ] = None,
    bpm: Annotated[
        float | None,
        typer.Option(help="Tempo in beats per minute (default with --music: estimated)."),
    ] = None,
    genre: Annotated[str | None, typer.Option(help="Genre label of the sequences.")] = None,
    manifest: Annotated[
        Path | None,
        typer.Option(
            help="CSV with columns bvh (required), music, bpm, genre, split; paths relative to "
            "the CSV. Pairs many files with their music."
        ),
    ] = None,
    append: Annotated[
        bool,
        typer.Option(
            help="Keep the latest version's sequences and add these (same skeleton). Default: "
            "the new version holds only these files."
        ),
    ] = False,
    up_axis: Annotated[str, typer.Option(help="Up axis recorded in the motion attrs.")] = "y",
    glob: Annotated[
        str, typer.Option(help="File-name pattern of the BVH files in folders given as PATHS.")
    ] = "*.bvh",
    frames: Annotated[
        str,
        typer.Option(
            help="declared: refuse a MOTION block whose row count differs from 'Frames:'; "
            "present: read every row (both counts go into the manifest)."
        ),
    ] = "declared",
    workers: Workers = 1,
    dask: Dask = None,
    on_error: OnErrorOpt = OnError.fail,
    wait: Wait = False,
    quiet: Quiet = False,
    as_json: Json = False,
) -> None:
    """Read BVH files into a new store version: skeleton (offsets, channel layout, per-joint
    Euler orders, End Sites) in the motion attrs; trans, axis_angle, euler (each joint's own
    order) and positions (forward kinematics) in metres and radians."""
    setup(quiet)
    from dancedata.ingest.bvh import BvhIngestOptions
    from dancedata.ingest.engine import ingest
    from dancedata.ingest.registry import source_named

    options = BvhIngestOptions(
        units=units,
        fps=fps,
        smooth_cutoff_hz=smooth_cutoff,
        smooth_order=smooth_order,
        check_size=size_check,
        up_axis=up_axis,
        music=music,
        bpm=bpm,
        genre=genre,
        manifest=manifest,
        append=append,
        on_error=on_error.value,
        wait_for_lock=wait,
        glob=glob,
        frames=frames,
        workers=workers,
        dask=dask,
    )
    from dancedata.store.first_write import remove_store_if_left_empty

    with remove_store_if_left_empty(store):  # a failed first ingest leaves no empty store
        result = ingest(store, source_named("bvh")(list(paths or []), options))
    report(result, "ingest bvh", as_json, store=str(store))
