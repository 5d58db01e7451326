"""The BVH source: ``dancedata ingest bvh``'s options (:class:`Options`); the source is
:mod:`dancedata.ingest.bvh.source`, whose names (``BvhSource``, ``ingest_bvh``,
``BvhIngestOptions``) are importable from here too."""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Any

from dancedata.ingest.options import IngestOptions, argument, common, option, source_exports

__getattr__ = source_exports(__name__)


@dataclass(kw_only=True)
class Options(IngestOptions):
    """Read BVH files into a new store version: skeleton (offsets, channel layout, per-joint
    Euler orders, End Sites) in the motion attrs; trans, axis_angle, euler (each joint's own
    order) and positions (forward kinematics) in metres and radians."""

    paths: list[Path] | None = argument(
        None,
        help="BVH files or folders (searched recursively for --glob); each file becomes "
        "one sequence named after its file stem. May be left out when --manifest lists the "
        "files.",
    )
    store: Path = option(help="Store directory (created if new).", flags=("--store", "-s"))
    units: str = option(
        "cm",
        help="Length unit of the files: m, cm, mm, in, ft, dm, or metres per unit as a "
        "number (CMU cgspeed BVH: 0.056444). Stored lengths are metres.",
    )
    size_check: bool = option(
        True, help="Refuse rigs smaller than 0.3 m or larger than 3 m (a wrong --units)."
    )
    fps: float | None = option(
        None,
        help="Resample to this frame rate: every k-th frame for an integer ratio, "
        "SLERP otherwise. Default: the files' own rate (all files must share it).",
    )
    smooth_cutoff: float | None = option(
        None,
        help="Low-pass joint rotations at this cut-off (Hz): zero-phase Butterworth on "
        "sign-continuous quaternions, before resampling.",
    )
    smooth_order: int = option(2, min=1, help="Butterworth order.")
    music: Path | None = option(None, help="Music of the (single) BVH file; featurize analyses it.")
    bpm: float | None = option(
        None, help="Tempo in beats per minute (default with --music: estimated)."
    )
    genre: str | None = option(None, help="Genre label of the sequences.")
    manifest: Path | None = option(
        None,
        help="CSV with columns bvh (required), music, bpm, genre, split; paths relative to "
        "the CSV. Pairs many files with their music.",
    )
    append: bool = option(
        False,
        help="Keep the latest version's sequences and add these (same skeleton). Default: "
        "the new version holds only these files.",
    )
    up_axis: str = option("y", help="Up axis recorded in the motion attrs.")
    glob: str = option(
        "*.bvh", help="File-name pattern of the BVH files in folders given as PATHS."
    )
    frames: str = option(
        "declared",
        help="declared: refuse a MOTION block whose row count differs from 'Frames:'; "
        "present: read every row (both counts go into the manifest).",
    )
    workers: int = common("workers", 1)
    dask: str | None = common("dask", None)
    on_error: str = common("on_error", "fail")
    wait: bool = common("wait", False)

    def run(self) -> Any:
        from dancedata.ingest.bvh.source import BvhIngestOptions
        from dancedata.ingest.options import ingest_into

        options = BvhIngestOptions(
            units=self.units,
            fps=self.fps,
            smooth_cutoff_hz=self.smooth_cutoff,
            smooth_order=self.smooth_order,
            check_size=self.size_check,
            up_axis=self.up_axis,
            music=self.music,
            bpm=self.bpm,
            genre=self.genre,
            manifest=self.manifest,
            append=self.append,
            on_error=self.on_error,
            wait_for_lock=self.wait,
            glob=self.glob,
            frames=self.frames,
            workers=self.workers,
            dask=self.dask,
        )
        return ingest_into(self.store, "bvh", list(self.paths or []), options)
