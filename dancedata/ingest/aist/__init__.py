"""The AIST++ source: ``dancedata ingest aist``'s options (:class:`Options`); the source is
:mod:`dancedata.ingest.aist.source`, whose names (``AistSource``, ``ingest_aist``,
``AistIngestOptions``) are importable from here too."""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Any

from dancedata.ingest.options import IngestOptions, argument, common, option, source_exports

__getattr__ = source_exports(__name__)


def _csv(text: str | None) -> list[str] | None:
    """``gBR,gPO`` → ["gBR", "gPO"] (blanks dropped); None for None or no item."""
    if text is None:
        return None
    return [part.strip() for part in text.split(",") if part.strip()] or None


@dataclass(kw_only=True)
class Options(IngestOptions):
    """Read AIST++ motion and keypoint pickles (safely: nothing in them is executed), cameras,
    splits (crossmodal, pose), ignore list and music into a new store version. Lengths are
    stored in metres: translation = smpl_trans / smpl_scaling, keypoints3d and camera
    translation cm / 100.

    Example:
      dancedata ingest aist data/raw/aist-demo --store data/stores/aist-20fps --fps 20
    """

    raw: Path = argument(help="AIST++ annotation root (motions/, splits/, ...).")
    store: str = option(
        help="Store directory or fsspec URL (created if new).", flags=("--store", "-s")
    )
    music_dir: Path | None = option(
        None, help="Folder of <music_id>.wav/.mp3/.flac (default: RAW/wav or RAW/music)."
    )
    allow_missing_music: bool = option(
        False, help="Keep sequences whose music is missing and record the gap."
    )
    genres: str | None = option(None, help="Only these genres, comma-separated (e.g. gBR,gPO).")
    exclude_genres: str | None = option(
        None, help="Drop these genres (the keyframe study drops gJB)."
    )
    situations: str | None = option(
        None, help="Only these situations: sBM (basic), sFM (advanced)."
    )
    annotations: str | None = option(
        None,
        help="Annotation kinds to store, comma-separated: keypoints3d, keypoints2d, cameras "
        "(default: every kind on disk; '' for none). Sequences lacking a kind get NaN rows.",
    )
    fps: str | None = option(
        None,
        flags=("--fps",),
        metavar="FPS",
        help="Store the motion at this frame rate (AIST++ is 60 fps): the 60 fps ingest, "
        "then `dancedata resample --fps FPS` as the next version (SLERP rotations, linear "
        "positions; see its --help).",
    )
    on_error: str = common("on_error", "fail")
    workers: int = common("workers", 1)
    dask: str | None = common("dask", None)
    wait: bool = common("wait", False)

    def run(self) -> Any:
        """The 60 fps ingest, then (``--fps``) the resampled version."""
        from dancedata.featurize.resample_store import check_fps
        from dancedata.ingest.aist.inputs import AIST_FPS, AistIngestOptions
        from dancedata.ingest.options import ingest_into

        target_fps = None if self.fps is None else check_fps(self.fps)
        options = AistIngestOptions(
            music_dir=self.music_dir,
            allow_missing_music=self.allow_missing_music,
            genres=_csv(self.genres),
            exclude_genres=_csv(self.exclude_genres),
            situations=_csv(self.situations),
            annotations=(_csv(self.annotations) or []) if self.annotations is not None else None,
            on_error=self.on_error,
            wait_for_lock=self.wait,
            workers=self.workers,
            dask=self.dask,
        )
        from dancedata.store.backend_open import make_backend

        store = make_backend(self.store)  # one handle for the ingest and the resample after it
        result = ingest_into(store, "aist", self.raw, options)
        if target_fps is not None and target_fps != AIST_FPS:
            from dancedata.featurize.resample_store import resample_version

            ingested = result.version
            result = resample_version(store, target_fps, version=ingested)
            result.counts = {**(result.counts or {}), "ingest_version": ingested}
        return result
