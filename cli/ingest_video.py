"""``dancedata ingest video``: video-derived poses aligned to the video's clock."""

from __future__ import annotations

from enum import StrEnum
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


class Units(StrEnum):
    m = "m"
    cm = "cm"
    mm = "mm"


class Select(StrEnum):
    area = "area"
    frames = "frames"


class FrameTimes(StrEnum):
    nominal = "nominal"
    decoded = "decoded"


class CsvSkeleton(StrEnum):
    body25 = "body25"
    coco18 = "coco18"
    h36m17 = "h36m17"
    spin24 = "spin24"
    hmr19 = "hmr19"


@ingest_app.command("video")
def ingest_video_cmd(
    store: Annotated[Path, typer.Option("--store", "-s", help="Store directory (created if new).")],
    videos: Annotated[
        list[Path] | None,
        typer.Argument(
            help="Video files; each becomes one sequence named after its file stem. None: the "
            "pose files alone, with --fps (sequences named after the OpenPose file prefix, "
            "frames numbered from the file names)."
        ),
    ] = None,
    poses: Annotated[
        Path | None,
        typer.Option(
            help="OpenPose --write_json output. Per video: DIR/<stem>/ if it exists, else the "
            "files DIR/<stem>_<frame>_keypoints.json; with one video, also a folder of "
            "*_keypoints.json with any prefix."
        ),
    ] = None,
    joints_csv: Annotated[
        Path | None,
        typer.Option(
            help="3-d joints from a pose lifter, instead of or with --poses: a CSV (one video) "
            "or a folder of <stem>.csv. Header columns <joint>_x/_y/_z (BODY_25, COCO-18, "
            "H36M-17, SPIN-24 or HMR-19 names take that skeleton), optional frame or time "
            "column; stored in motion/positions."
        ),
    ] = None,
    skeleton: Annotated[
        CsvSkeleton | None,
        typer.Option(help="Joint names of a headerless --joints-csv (x, y, z per joint)."),
    ] = None,
    frame_base: Annotated[
        int, typer.Option(help="Number of the video's first frame in a CSV frame column.")
    ] = 0,
    units: Annotated[Units, typer.Option(help="Units of --joints-csv (stored in metres).")] = (
        Units.m
    ),
    person: Annotated[
        int | None,
        typer.Option(
            help="Follow this person: an OpenPose person id (when run with --tracking), else a "
            "tracklet number (0, 1, ... by first appearance, left to right). Default: the "
            "largest person present in at least half as many frames as the most seen."
        ),
    ] = None,
    select: Annotated[
        Select, typer.Option(help="Default dancer: largest (area) or most often seen (frames).")
    ] = Select.area,
    max_gap: Annotated[
        int,
        typer.Option(
            min=0, help="Interpolate joints missing for up to this many video frames (0: none)."
        ),
    ] = 3,
    allow_drift: Annotated[
        bool,
        typer.Option(
            help="Accept pose and video frame counts that differ: keep the frames both have and "
            "record the drift."
        ),
    ] = False,
    fps: Annotated[
        float | None,
        typer.Option(
            help="Stored frame rate; poses are resampled by timestamp. Default: the video's. "
            "Without a video: the rate the poses were taken at (required)."
        ),
    ] = None,
    frame_times: Annotated[
        FrameTimes,
        typer.Option(
            help="Time of video frame i: nominal i / fps, or decoded (the frame's presentation "
            "time, for variable-frame-rate video; decodes the whole video)."
        ),
    ] = FrameTimes.nominal,
    music: Annotated[
        Path | None,
        typer.Option(
            help="Music file (shared by every video) or folder of <stem>.wav/.flac/.ogg/.mp3. "
            "Default: the video's audio track, read with PyAV (the 'viz' extra). It starts with "
            "the video."
        ),
    ] = None,
    no_music: Annotated[bool, typer.Option(help="Store no music (ignore audio tracks).")] = False,
    bpm: Annotated[
        float | None,
        typer.Option(
            help="Tempo of the music; default: estimated (librosa beat_track) and "
            "recorded as bpm_estimated."
        ),
    ] = None,
    genre: Annotated[str | None, typer.Option(help="Genre label of every sequence.")] = None,
    up_axis: Annotated[
        str, typer.Option(help="Up axis recorded in the motion attrs (image frames: -y).")
    ] = "-y",
    workers: Workers = 1,
    dask: Dask = None,
    on_error: OnErrorOpt = OnError.fail,
    wait: Wait = False,
    quiet: Quiet = False,
    as_json: Json = False,
) -> None:
    """Read OpenPose JSON and/or 3-d joint CSVs made from videos, follow one dancer, align the
    poses to each video's clock (pose frame i at i / video fps) and resample them by timestamp
    into a new store version: motion/pose2d (x, y px, confidence; NaN where missing) with
    motion/pose2d_mask (0 missing, 1 detected, 2 gap-filled), motion/positions (metres).
    Pose and video frame counts must agree unless --allow-drift. Without VIDEO, the pose files
    are the clock: give --fps; pose frame i (from the file name) is at i / fps. Videos are read
    on --workers processes (or --dask); a killed run, run again, reads only the videos it had
    not finished."""
    setup(quiet)
    from dancedata.ingest.video import VideoIngestOptions, ingest_video
    from dancedata.ingest.video.poses import PoseSettings

    options = VideoIngestOptions(
        poses=poses,
        joints_csv=joints_csv,
        music=music,
        no_music=no_music,
        bpm=bpm,
        genre=genre,
        up_axis=up_axis,
        settings=PoseSettings(
            fps=fps,
            person=person,
            select=select.value,
            max_gap=max_gap,
            allow_drift=allow_drift,
            units=units.value,
            skeleton=None if skeleton is None else skeleton.value,
            frame_base=frame_base,
            frame_times=frame_times.value,
        ),
        on_error=on_error.value,
        wait_for_lock=wait,
        workers=workers,
        dask=dask,
    )
    from dancedata.store.first_write import remove_store_if_left_empty

    with remove_store_if_left_empty(store):  # a failed first ingest leaves no empty store
        result = ingest_video(store, videos or [], options)
    report(result, "ingest video", as_json, store=str(store))
    if not as_json:
        for line in _notes(result.counts.get("videos", {})):
            typer.echo(line, err=True)


def _notes(videos: dict) -> list[str]:
    """One stderr line per video worth a look: drift kept, identity switches, estimated tempo."""
    lines = []
    for seq_id, rep in videos.items():
        notes = []
        if rep.get("drift_frames"):
            notes.append(
                f"drift {rep['drift_frames']:+d} frames allowed, {rep['video_frames_used']} "
                "video frames kept"
            )
        switches = rep.get("tracking", {}).get("switch_frames") or []
        if switches:
            notes.append(f"{len(switches)} identity switch(es) at frames {switches[:10]}")
        music = rep.get("music") or {}
        if music.get("bpm_estimated"):
            notes.append(f"tempo estimated: {music['bpm']:.2f} BPM")
        if notes:
            lines.append(f"  {seq_id}: " + "; ".join(notes))
    return lines
