"""``dancedata ingest aist``: AIST++ annotations into a new store version."""

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
    split_csv,
)


@ingest_app.command("aist")
def ingest_aist_cmd(
    raw: Annotated[Path, typer.Argument(help="AIST++ annotation root (motions/, splits/, ...).")],
    store: Annotated[
        str,
        typer.Option("--store", "-s", help="Store directory or fsspec URL (created if new)."),
    ],
    music_dir: Annotated[
        Path | None,
        typer.Option(help="Folder of <music_id>.wav/.mp3/.flac (default: RAW/wav or RAW/music)."),
    ] = None,
    allow_missing_music: Annotated[
        bool, typer.Option(help="Keep sequences whose music is missing and record the gap.")
    ] = False,
    genres: Annotated[
        str | None, typer.Option(help="Only these genres, comma-separated (e.g. gBR,gPO).")
    ] = None,
    exclude_genres: Annotated[
        str | None, typer.Option(help="Drop these genres (the keyframe study drops gJB).")
    ] = None,
    situations: Annotated[
        str | None, typer.Option(help="Only these situations: sBM (basic), sFM (advanced).")
    ] = None,
    annotations: Annotated[
        str | None,
        typer.Option(
            help="Annotation kinds to store, comma-separated: keypoints3d, keypoints2d, cameras "
            "(default: every kind on disk; '' for none). Sequences lacking a kind get NaN rows."
        ),
    ] = None,
    fps: Annotated[
        str | None,
        typer.Option(
            "--fps",
            metavar="FPS",
            help="Store the motion at this frame rate (AIST++ is 60 fps): the 60 fps ingest, "
            "then `dancedata resample --fps FPS` as the next version (SLERP rotations, linear "
            "positions; see its --help).",
        ),
    ] = None,
    on_error: OnErrorOpt = OnError.fail,
    workers: Workers = 1,
    dask: Dask = None,
    wait: Wait = False,
    quiet: Quiet = False,
    as_json: Json = False,
) -> None:
    """Read AIST++ motion and keypoint pickles (safely: nothing in them is executed), cameras,
    splits (crossmodal, pose), ignore list and music into a new store version. Lengths are
    stored in metres: translation = smpl_trans / smpl_scaling, keypoints3d and camera
    translation cm / 100.

    Example:
      dancedata ingest aist data/raw/aist-demo --store data/stores/aist-20fps --fps 20
    """
    setup(quiet)
    from dancedata.featurize.resample_store import check_fps
    from dancedata.ingest.aist.inputs import AIST_FPS

    target_fps = None if fps is None else check_fps(fps)
    from dancedata.ingest.aist import AistIngestOptions
    from dancedata.ingest.engine import ingest
    from dancedata.ingest.registry import source_named

    options = AistIngestOptions(
        music_dir=music_dir,
        allow_missing_music=allow_missing_music,
        genres=split_csv(genres),
        exclude_genres=split_csv(exclude_genres),
        situations=split_csv(situations),
        annotations=(split_csv(annotations) or []) if annotations is not None else None,
        on_error=on_error.value,
        wait_for_lock=wait,
        workers=workers,
        dask=dask,
    )
    from dancedata.store.first_write import remove_store_if_left_empty

    with remove_store_if_left_empty(store):  # a failed first ingest leaves no empty store
        result = ingest(store, source_named("aist")(raw, options))
    if target_fps is not None and target_fps != AIST_FPS:
        from dancedata.featurize.resample_store import resample_version

        ingested = result.version
        result = resample_version(store, target_fps, version=ingested)
        result.counts = {**(result.counts or {}), "ingest_version": ingested}
    report(result, "ingest aist", as_json, store=str(store))
