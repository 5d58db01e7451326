"""``dancedata featurize`` and ``dancedata segment``."""

from __future__ import annotations

from pathlib import Path
from typing import Annotated

import typer
from dancedata.cli.common import Json, Quiet, VersionOpt, Wait, report, setup, split_csv
from dancedata.cli.main import app


@app.command()
def featurize(
    store: Annotated[Path, typer.Argument(help="Store directory.")],
    representations: Annotated[
        str,
        typer.Option(help="Motion representations, comma-separated: rotmat,euler,quat,rot6d."),
    ] = "rotmat,euler,quat,rot6d",
    euler_order: Annotated[
        str | None,
        typer.Option(
            help="scipy Euler order for every joint: upper case intrinsic, lower case extrinsic. "
            "Default: each joint's own order where the rig has one (BVH), else XYZ."
        ),
    ] = None,
    motion: Annotated[bool, typer.Option(help="Compute motion representations.")] = True,
    audio: Annotated[bool, typer.Option(help="Compute audio features (once per track).")] = True,
    version: VersionOpt = None,
    wait: Wait = False,
    quiet: Quiet = False,
    as_json: Json = False,
) -> None:
    """Add motion representations and FACT audio features (onset_env, mfcc, chroma_cens,
    onset_peaks, beats at fps × 512 Hz, hop 512) as a new version."""
    setup(quiet)
    from dancedata.pipeline.featurize import FeaturizeOptions
    from dancedata.pipeline.featurize import featurize as run

    options = FeaturizeOptions(
        motion=motion,
        audio=audio,
        representations=split_csv(representations) or [],
        euler_order=euler_order,
        version=version,
        wait_for_lock=wait,
    )
    report(run(store, options), "featurize", as_json)


@app.command()
def segment(
    store: Annotated[Path, typer.Argument(help="Store directory.")],
    beats_per_measure: Annotated[int, typer.Option(min=1, help="Beats in one measure.")] = 4,
    phase: Annotated[
        float, typer.Option(help="Downbeat offset in frames (0: the sequence starts on one).")
    ] = 0.0,
    version: VersionOpt = None,
    wait: Wait = False,
    quiet: Quiet = False,
    as_json: Json = False,
) -> None:
    """Write the measures table: frames per measure = 60 / bpm × beats_per_measure × fps,
    complete measures only, as a new version."""
    setup(quiet)
    from dancedata.pipeline.segment import SegmentOptions
    from dancedata.pipeline.segment import segment as run

    options = SegmentOptions(
        beats_per_measure=beats_per_measure,
        phase_frames=phase,
        version=version,
        wait_for_lock=wait,
    )
    report(run(store, options), "segment", as_json)
