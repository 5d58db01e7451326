"""The video-poses source: ``dancedata ingest video``'s options (:class:`Options`); the source
is :mod:`dancedata.ingest.video.source`, whose names (``VideoSource``, ``ingest_video``,
``VideoIngestOptions``) are importable from here too."""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Any

from dancedata.ingest.options import IngestOptions, argument, common, option, source_exports

__getattr__ = source_exports(__name__)

CSV_SKELETONS = ("body25", "coco18", "h36m17", "spin24", "hmr19")


@dataclass(kw_only=True)
class Options(IngestOptions):
    """Read OpenPose JSON and/or 3-d joint CSVs made from videos, follow one dancer, align the
    poses to each video's clock (pose frame i at i / video fps) and resample them by timestamp
    into a new store version: motion/pose2d (x, y px, confidence; NaN where missing) with
    motion/pose2d_mask (0 missing, 1 detected, 2 gap-filled), motion/positions (metres).
    Pose and video frame counts must agree unless --allow-drift. Without VIDEO, the pose files
    are the clock: give --fps; pose frame i (from the file name) is at i / fps. Videos are read
    on --workers processes (or --dask); a killed run, run again, reads only the videos it had
    not finished."""

    store: Path = option(help="Store directory (created if new).", flags=("--store", "-s"))
    videos: list[Path] | None = argument(
        None,
        help="Video files; each becomes one sequence named after its file stem. None: the "
        "pose files alone, with --fps (sequences named after the OpenPose file prefix, "
        "frames numbered from the file names).",
    )
    poses: Path | None = option(
        None,
        help="OpenPose --write_json output. Per video: DIR/<stem>/ if it exists, else the "
        "files DIR/<stem>_<frame>_keypoints.json; with one video, also a folder of "
        "*_keypoints.json with any prefix.",
    )
    joints_csv: Path | None = option(
        None,
        help="3-d joints from a pose lifter, instead of or with --poses: a CSV (one video) "
        "or a folder of <stem>.csv. Header columns <joint>_x/_y/_z (BODY_25, COCO-18, "
        "H36M-17, SPIN-24 or HMR-19 names take that skeleton), optional frame or time "
        "column; stored in motion/positions.",
    )
    skeleton: str | None = option(
        None,
        choices=CSV_SKELETONS,
        help="Joint names of a headerless --joints-csv (x, y, z per joint).",
    )
    frame_base: int = option(0, help="Number of the video's first frame in a CSV frame column.")
    units: str = option(
        "m", choices=("m", "cm", "mm"), help="Units of --joints-csv (stored in metres)."
    )
    person: int | None = option(
        None,
        help="Follow this person: an OpenPose person id (when run with --tracking), else a "
        "tracklet number (0, 1, ... by first appearance, left to right). Default: the "
        "largest person present in at least half as many frames as the most seen.",
    )
    select: str = option(
        "area",
        choices=("area", "frames"),
        help="Default dancer: largest (area) or most often seen (frames).",
    )
    max_gap: int = option(
        3, min=0, help="Interpolate joints missing for up to this many video frames (0: none)."
    )
    allow_drift: bool = option(
        False,
        help="Accept pose and video frame counts that differ: keep the frames both have and "
        "record the drift.",
    )
    fps: float | None = option(
        None,
        help="Stored frame rate; poses are resampled by timestamp. Default: the video's. "
        "Without a video: the rate the poses were taken at (required).",
    )
    frame_times: str = option(
        "nominal",
        choices=("nominal", "decoded"),
        help="Time of video frame i: nominal i / fps, or decoded (the frame's presentation "
        "time, for variable-frame-rate video; decodes the whole video).",
    )
    music: Path | None = option(
        None,
        help="Music file (shared by every video) or folder of <stem>.wav/.flac/.ogg/.mp3. "
        "Default: the video's audio track, read with PyAV (the 'viz' extra). It starts with "
        "the video.",
    )
    no_music: bool = option(False, help="Store no music (ignore audio tracks).")
    bpm: float | None = option(
        None,
        help="Tempo of the music; default: estimated (librosa beat_track) and "
        "recorded as bpm_estimated.",
    )
    genre: str | None = option(None, help="Genre label of every sequence.")
    up_axis: str = option("-y", help="Up axis recorded in the motion attrs (image frames: -y).")
    workers: int = common("workers", 1)
    dask: str | None = common("dask", None)
    on_error: str = common("on_error", "fail")
    wait: bool = common("wait", False)

    def run(self) -> Any:
        from dancedata.ingest.options import ingest_into
        from dancedata.ingest.video.poses import PoseSettings
        from dancedata.ingest.video.source import VideoIngestOptions

        options = VideoIngestOptions(
            poses=self.poses,
            joints_csv=self.joints_csv,
            music=self.music,
            no_music=self.no_music,
            bpm=self.bpm,
            genre=self.genre,
            up_axis=self.up_axis,
            settings=PoseSettings(
                fps=self.fps,
                person=self.person,
                select=self.select,
                max_gap=self.max_gap,
                allow_drift=self.allow_drift,
                units=self.units,
                skeleton=self.skeleton,
                frame_base=self.frame_base,
                frame_times=self.frame_times,
            ),
            on_error=self.on_error,
            wait_for_lock=self.wait,
            workers=self.workers,
            dask=self.dask,
        )
        return ingest_into(self.store, "video", self.videos or [], options)

    def notes(self, result: Any, quiet: bool) -> list[str]:
        """One stderr line per video worth a look: drift kept, identity switches, estimated
        tempo."""
        lines = []
        for seq_id, rep in result.counts.get("videos", {}).items():
            notes = []
            if rep.get("drift_frames"):
                notes.append(
                    f"drift {rep['drift_frames']:+d} frames allowed, "
                    f"{rep['video_frames_used']} video frames kept"
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
