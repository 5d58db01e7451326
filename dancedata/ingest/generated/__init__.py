"""The generated-motion source: ``dancedata ingest generated``'s options (:class:`Options`);
the source is :mod:`dancedata.ingest.generated.source`, whose names (``GeneratedSource``,
``ingest_generated``, ``GeneratedIngestOptions``, ``flip_lines``) are importable from here too."""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Any, ClassVar

from dancedata.ingest.options import IngestOptions, argument, common, option, source_exports

__getattr__ = source_exports(__name__)


@dataclass(kw_only=True)
class Options(IngestOptions):
    """Ingest a model's generated motion into a store with the reference's skeleton, frame rate
    and music, so render, plot, export bvh and evaluate (store against store) work on it. Files
    named by no sequence of the reference are refused (--on-error skip records them).

    Example:
      dancedata ingest generated out/lstm --store data/stores/lstm --like data/stores/aist
      --smooth-cutoff 6 --repair-hip-flips
    """

    notes_err: ClassVar[bool] = False  # the flip lines go to stdout

    folder: Path = argument(
        help="Folder of generated motion, one <seq_id>.npy|.npz|.pkl per sequence of the "
        "reference (EDGE's <prefix>_<seq_id>.pkl too): FACT 225-d rows, smpl_poses + "
        "smpl_trans, axis_angle or quat + trans, or (F, J, 3) joint positions."
    )
    store: Path = option(help="Store to write (created if new).", flags=("--store", "-s"))
    like: Path = option(
        help="Reference store: its skeleton, frame rate, music, sequence metadata and "
        "splits are taken by seq_id."
    )
    like_version: str | None = option(
        None, help="Version of the reference store (default: latest)."
    )
    generated_fps: float | None = option(
        None,
        help="Frame rate of the files (EDGE: 30); resampled to the reference's (decimation "
        "or SLERP). Default: the reference's.",
    )
    generated_up_axis: str = option(
        "y", help="Up axis of the files: y (SMPL, FACT, Bailando) or z (EDGE)."
    )
    smooth_cutoff: float | None = option(
        None,
        help="Zero-phase Butterworth low-pass cutoff in Hz (scipy sosfiltfilt; gain 1/2 at "
        "the cutoff) of rotations (sign-continuous quaternions), translation and positions.",
    )
    smooth_order: int = option(2, help="Butterworth order per pass (effective order twice that).")
    repair_hip_flips: bool = option(
        False,
        flags=("--repair-hip-flips",),
        help="Detect half-turn flips of the root rotation between frames and undo them "
        "(before smoothing); what is found is printed and recorded in the manifest.",
    )
    flip_threshold: float = option(
        90.0, help="Root rotation step (degrees per frame) counted as a flip."
    )
    on_error: str = common("on_error", "fail")
    workers: int = common("workers", 1)
    wait: bool = common("wait", False)

    def run(self) -> Any:
        from dancedata.ingest.generated.source import GeneratedIngestOptions
        from dancedata.ingest.options import ingest_into

        options = GeneratedIngestOptions(
            like=self.like,
            like_version=self.like_version,
            generated_fps=self.generated_fps,
            up_axis=self.generated_up_axis,
            smooth_cutoff=self.smooth_cutoff,
            smooth_order=self.smooth_order,
            repair_hip_flips=self.repair_hip_flips,
            flip_threshold_deg=self.flip_threshold,
            on_error=self.on_error,
            wait_for_lock=self.wait,
            workers=self.workers,
        )
        return ingest_into(self.store, "generated", self.folder, options)

    def notes(self, result: Any, quiet: bool) -> list[str]:
        """The hip flips repaired, per sequence (not with --quiet)."""
        from dancedata.ingest.generated.source import flip_lines

        return [] if quiet else flip_lines(result)
