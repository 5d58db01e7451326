"""The AIST++ ingest source (``dancedata ingest aist``): annotations and music as records for
the ingest engine (:mod:`dancedata.ingest.engine`).

One read task per sequence (motion, keypoints3d and keypoints2d pickles, read safely); the
engine streams them into frame-concatenated arrays, so memory is bounded by one read batch and
one chunk per array whatever the dataset size. Tables: sequences, music, splits and cameras (a
few hundred bytes per sequence). Music is only described here (sample rate, length, feature
frame range); featurize decodes it.
"""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np

from dancedata.compute.smpl import SMPL_JOINTS, SMPL_PARENTS
from dancedata.errors import InputError
from dancedata.ingest.aist.annotations import (
    SequenceAnnotations,
    annotation_arrays,
    annotation_rows,
    read_annotations,
)
from dancedata.ingest.aist.camera_inputs import cameras_table_rows
from dancedata.ingest.aist.inputs import (
    AIST_FPS,
    AistIngestOptions,
    check_music_length,
    describe_inputs,
    find_inventory,
    music_rows,
    sequence_files,
    used_music,
)
from dancedata.ingest.aist.splits import split_rows
from dancedata.ingest.engine import ingest
from dancedata.ingest.registry import register_source
from dancedata.ingest.source import (
    Finished,
    IngestPlan,
    IngestTotals,
    InputChecksums,
    MusicTable,
    ReadTask,
    SequenceRecord,
    SkipPolicy,
    Source,
    StoredArray,
)
from dancedata.io.aist import AistMotion, read_motion
from dancedata.io.aist_names import music_bpm
from dancedata.store.command_result import CommandResult

__all__ = ["AistIngestOptions", "AistSource", "ingest_aist"]


def _read_sequence(
    files: tuple[str, str | None, str | None],
) -> tuple[AistMotion, SequenceAnnotations]:
    """One read task item: a sequence's motion and keypoint pickles, read and checked."""
    motion, kp3d, kp2d = files
    seq = read_motion(motion)
    keypoints = read_annotations(
        None if kp3d is None else Path(kp3d),
        None if kp2d is None else Path(kp2d),
        seq.n_frames,
        AIST_FPS,
    )
    return seq, keypoints


def _annotations_missing(records: list[SequenceRecord]) -> dict[str, int]:
    """Per annotation kind (and music), how many stored sequences lack it."""
    return {
        "keypoints3d": sum(not r.columns["has_keypoints3d"] for r in records),
        "keypoints2d": sum(not r.columns["has_keypoints2d"] for r in records),
        "cameras": sum(r.columns["camera_setting"] is None for r in records),
        "music": sum(r.music_key is None for r in records),
    }


@register_source("aist")
class AistSource(Source):
    """AIST++ annotation root ``raw`` (motions/, keypoints3d/, keypoints2d/, cameras/,
    splits/, ignore list) and its music, as engine records (:mod:`dancedata.ingest.source`)."""

    command = "ingest aist"

    def __init__(self, raw: str | Path, options: AistIngestOptions) -> None:
        self.raw = Path(raw)
        self.options = options
        self.on_error = options.on_error

    # -- before the version opens ----------------------------------------------------------
    def plan(self, store: str | Path, checksums: InputChecksums, skips: SkipPolicy) -> IngestPlan:
        if not self.raw.is_dir():
            raise InputError("no such directory", self.raw)
        inventory = self.inventory = find_inventory(self.raw, self.options)
        skips.skipped.extend(inventory.skipped)
        inputs = describe_inputs(inventory)
        self.checksums = {i["path"]: i["sha256"] for i in inputs}
        self.names = {str(inventory.motion_paths[n.seq_id]): n for n in inventory.names}
        self.stored_annotations = annotation_arrays(
            keypoints3d=bool(inventory.keypoints3d_paths),
            keypoints2d=bool(inventory.keypoints2d_paths),
        )
        return IngestPlan(
            config=self.options.config(),
            fingerprint_keys=[i["sha256"] for i in inputs],
            inputs=inputs,
            tasks=[
                ReadTask(str(inventory.motion_paths[n.seq_id]), sequence_files(inventory, n.seq_id))
                for n in inventory.names
            ],
            parse=_read_sequence,
            task_kind="sequences",
            arrays=[
                StoredArray("trans", (3,), np.float32, attrs={"units": "m"}),
                StoredArray("axis_angle", (24, 3), np.float32, attrs={"units": "rad"}),
                *self.stored_annotations,
            ],
            read_desc="read sequences",
            sequences_desc="ingest sequences",
            sequences_unit="seq",
            workers=self.options.workers,
            dask=self.options.dask,
            wait_for_lock=self.options.wait_for_lock,
            empty_error=InputError("every motion was skipped; nothing to ingest", self.raw),
        )

    def prepare(self, checksums: InputChecksums, skips: SkipPolicy) -> None:
        """Read the music headers (frame counts); unreadable tracks skip their sequences."""
        self.music_rows, self.music_frames, self.unreadable_music = music_rows(
            self.inventory, self.options.on_error
        )
        for row in self.music_rows:
            row["sha256"] = self.checksums[row["path"]]
        for error in self.unreadable_music.values():
            skips.skipped.append({"path": str(error.path or ""), "error": error.problem})

    # -- records ---------------------------------------------------------------------------
    def read(self, task: ReadTask, parsed: Callable[[], Any]) -> SequenceRecord:
        name = self.names[task.path]
        if name.music_id in self.unreadable_music:  # (before the parse's own error)
            bad = self.unreadable_music[name.music_id]
            raise InputError(f"its music {name.music_id} is unreadable ({bad.path})", task.path)
        seq, keypoints = parsed()
        music_available = self.music_frames.get(name.music_id)
        check_music_length(name.music_id, music_available, seq.n_frames, Path(task.path))
        annotation_arrays_, annotation_columns = annotation_rows(
            keypoints, seq.n_frames, self.stored_annotations
        )
        return SequenceRecord(
            seq_id=name.seq_id,
            source="aistpp",
            path=task.path,
            sha256=self.checksums[task.path],
            fps=AIST_FPS,
            n_frames=seq.n_frames,
            arrays={"trans": seq.trans_m, "axis_angle": seq.axis_angle, **annotation_arrays_},
            genre=name.genre,
            situation=name.situation,
            dancer=name.dancer,
            choreo=name.choreo,
            music_key=None if music_available is None else name.music_id,
            music_id=name.music_id,
            bpm=music_bpm(name.music_id),
            name_columns={"camera": name.camera},
            columns={
                "smpl_scaling": seq.scaling,
                "smpl_loss": seq.loss,
                "camera_setting": self.inventory.cameras.setting_of.get(name.seq_id),
                **annotation_columns,
            },
        )

    # -- tables ----------------------------------------------------------------------------
    def finish(self, records: list[SequenceRecord], totals: IngestTotals) -> Finished:
        rows = used_music(self.music_rows, {r.music_id for r in records if r.music_id})
        music = MusicTable(rows, {row["music_id"]: row for row in rows}, write_empty=True)
        present = {r.seq_id for r in records}
        inventory = self.inventory
        splits, split_counts = split_rows(inventory.split_files, inventory.ignore_file, present)
        used_settings = {
            r.columns["camera_setting"] for r in records if r.columns["camera_setting"]
        }
        cameras = cameras_table_rows(inventory.cameras, used_settings, self.checksums)
        skeleton = {"name": "smpl24", "joints": list(SMPL_JOINTS), "parents": list(SMPL_PARENTS)}
        counts = {
            "sequences": totals.sequences,
            "frames": totals.frames,
            "music": len(music.rows),
            "music_missing": sum(r.music_key is None for r in records),
            "camera_settings": len(used_settings),
            "annotations_missing": _annotations_missing(records),
            "skipped": totals.skipped,
            "splits": split_counts,
            **totals.read_counts,
        }
        return Finished(
            music=music,
            counts=counts,
            tables={"splits": splits, **({"cameras": cameras} if cameras else {})},
            attrs={"motion": {"fps": AIST_FPS, "up_axis": "y", "skeleton": skeleton}},
        )


def ingest_aist(store: str | Path, raw: str | Path, options: AistIngestOptions) -> CommandResult:
    """Ingest the AIST++ annotation root ``raw`` into a new version of ``store``."""
    return ingest(store, AistSource(raw, options))
