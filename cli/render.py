"""``dancedata render``: a sequence's skeleton as a video with its music."""

from __future__ import annotations

from pathlib import Path
from typing import Annotated

import typer
from dancedata.cli.common import Json, Quiet, VersionOpt, report, setup
from dancedata.cli.main import app


@app.command()
def render(
    store: Annotated[Path, typer.Argument(help="Store directory.")],
    seq_id: Annotated[str, typer.Argument(help="Sequence id (sequences.seq_id).")],
    out: Annotated[
        Path, typer.Argument(help="MP4 file to write (H.264 + AAC), or a .png for one still.")
    ],
    width: Annotated[int, typer.Option(help="Frame width in pixels (even).")] = 640,
    height: Annotated[int, typer.Option(help="Frame height in pixels (even).")] = 480,
    view: Annotated[
        str,
        typer.Option(
            help="Camera: front, side or top (orthographic; the store's up axis is up; video "
            "2-d poses: front only)."
        ),
    ] = "front",
    start: Annotated[int | None, typer.Option(help="First frame to render.")] = None,
    stop: Annotated[
        int | None, typer.Option(help="Frame to stop before (default: the end).")
    ] = None,
    source: Annotated[
        str,
        typer.Option(
            help="Joints to draw: auto (smpl with --smpl-model, else keypoints3d, positions, "
            "fk, pose2d: the first the store has), or one of those."
        ),
    ] = "auto",
    smpl_model: Annotated[
        Path | None,
        typer.Option(help="SMPL model (.npz/.pkl): draw SMPL joints from the stored rotations."),
    ] = None,
    compare: Annotated[
        list[str] | None,
        typer.Option(
            help="Another sequence drawn side by side: SEQ (same store) or STORE::SEQ. Repeat "
            "for more."
        ),
    ] = None,
    generated: Annotated[
        list[Path] | None,
        typer.Option(
            help="Generated motion drawn side by side: a file, or a folder of "
            "<seq_id>.npy/.npz/.pkl (positions (F, J, 3), FACT 225-d rows, or smpl_poses + "
            "smpl_trans). Repeat for more."
        ),
    ] = None,
    generated_fps: Annotated[
        float | None,
        typer.Option(help="Frame rate of generated motion (default: the sequence's)."),
    ] = None,
    audio: Annotated[bool, typer.Option(help="Mux the sequence's music in (AAC).")] = True,
    version: VersionOpt = None,
    quiet: Quiet = False,
    as_json: Json = False,
) -> None:
    """Render SEQ_ID's skeleton to OUT.mp4 at the sequence's fps, with its music, the current
    measure and beat. OUT.png writes the one frame at --start instead (a still). Needs the 'viz'
    extra: pip install 'dancedata[viz]'."""
    setup(quiet)
    from dancedata.viz.render import RenderOptions, render_sequence, render_still, require_av

    still = out.suffix.lower() == ".png"
    if not still:
        require_av()
    options = RenderOptions(
        width=width,
        height=height,
        view=view,
        start=start,
        stop=stop,
        source=source,
        smpl_model=smpl_model,
        compare=tuple(compare or ()),
        generated=tuple(generated or ()),
        generated_fps=generated_fps,
        audio=audio,
        version=version,
    )
    result = (render_still if still else render_sequence)(store, seq_id, out, options)
    report(result, "render", as_json)
