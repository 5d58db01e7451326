"""The AIST++ ingest source (``dancedata ingest aist``): annotations and music as records for
the ingest engine (:mod:`dancedata.ingest.engine`).

One read task per sequence (motion, keypoints3d and keypoints2d pickles, read safely); the
engine streams them into frame-concatenated arrays, so memory is bounded by one read batch and
one chunk per array whatever the dataset size. Tables: sequences, music, splits and cameras (a
few hundred bytes per sequence). Music is only described here (sample rate, length, feature
frame range); featurize decodes it.
"""

from __future__ import annotations

import os
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from dancedata.aist_names import (
    GENRES,
    SITUATIONS,
    SequenceName,
    music_bpm,
    music_genre,
    parse_sequence_name,
)
from dancedata.errors import InputError
from dancedata.ingest.aist_annotations import (
    ANNOTATION_KINDS,
    SequenceAnnotations,
    annotation_arrays,
    annotation_rows,
    read_annotations,
)
from dancedata.ingest.aist_camera_inputs import (
    CameraInputs,
    cameras_table_rows,
    find_camera_inputs,
)
from dancedata.ingest.aist_splits import split_rows
from dancedata.ingest.engine import ingest
from dancedata.ingest.registry import register_source
from dancedata.ingest.source import (
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
from dancedata.io.aist import AistMotion, find_ignore_list, find_split_files, read_motion
from dancedata.io.audio import audio_info, feature_frames, find_music, resampled_length
from dancedata.io.music_file import file_stamp
from dancedata.progress import progress
from dancedata.smpl import SMPL_JOINTS, SMPL_PARENTS
from dancedata.store.checksums import describe_input
from dancedata.store.command_result import CommandResult

AIST_FPS = 60.0
AUDIO_HOP = 512
AUDIO_SR = int(AIST_FPS * AUDIO_HOP)  # 30720 Hz: 60 feature frames per second at hop 512
# Music may end this many feature frames before its motion without failing the ingest.
MAX_MUSIC_SHORTFALL_FRAMES = 2


@dataclass
class AistIngestOptions:
    """Every setting of an AIST++ ingest; all of them change the data, so all are fingerprinted."""

    music_dir: Path | None = None
    allow_missing_music: bool = False
    genres: list[str] | None = None
    exclude_genres: list[str] | None = None
    situations: list[str] | None = None
    # Annotation kinds to store (keypoints3d, keypoints2d, cameras); None: every kind on disk.
    annotations: list[str] | None = None
    on_error: str = "fail"  # or "skip"
    wait_for_lock: bool = False
    # Processes reading pickles, or a Dask scheduler address / "local:N" (not fingerprinted:
    # the bytes do not depend on them).
    workers: int = 1
    dask: str | None = None

    def wants(self, kind: str) -> bool:
        return self.annotations is None or kind in self.annotations

    def config(self) -> dict[str, Any]:
        return {
            "fps": AIST_FPS,
            "audio_sr": AUDIO_SR,
            "audio_hop": AUDIO_HOP,
            "allow_missing_music": self.allow_missing_music,
            "genres": sorted(self.genres) if self.genres else None,
            "exclude_genres": sorted(self.exclude_genres) if self.exclude_genres else None,
            "situations": sorted(self.situations) if self.situations else None,
            "annotations": sorted(self.annotations) if self.annotations is not None else None,
            "on_error": self.on_error,
        }


@dataclass
class _Inventory:
    names: list[SequenceName]
    motion_paths: dict[str, Path]
    music_paths: dict[str, Path | None]
    split_files: dict[tuple[str, str], Path]
    ignore_file: Path | None
    keypoints3d_paths: dict[str, Path] = field(default_factory=dict)
    keypoints2d_paths: dict[str, Path] = field(default_factory=dict)
    cameras: CameraInputs = field(default_factory=CameraInputs)
    skipped: list[dict[str, str]] = field(default_factory=list)


def _music_dir(raw: Path, options: AistIngestOptions) -> Path:
    """The music folder, absolute: the music table records paths featurize opens later, maybe
    from another working directory."""
    if options.music_dir is not None:
        return options.music_dir.resolve()
    for candidate in (raw / "wav", raw / "music", raw / "audio"):
        if candidate.is_dir():
            return candidate.resolve()
    return (raw / "wav").resolve()


def _check_selection(options: AistIngestOptions) -> None:
    """Unknown genre, situation or annotation codes are an error, not an empty selection."""
    for option, given, known in (
        ("--genres", options.genres, GENRES),
        ("--exclude-genres", options.exclude_genres, GENRES),
        ("--situations", options.situations, SITUATIONS),
        ("--annotations", options.annotations, ANNOTATION_KINDS),
    ):
        unknown = sorted(set(given or ()) - set(known))
        if unknown:
            raise InputError(f"{option}: unknown {unknown}; known: {', '.join(known)}")


def _inventory(raw: Path, options: AistIngestOptions) -> _Inventory:
    _check_selection(options)
    motions_dir = raw / "motions"
    if not motions_dir.is_dir():
        raise InputError("no motions/ folder: not an AIST++ annotation root", raw)
    names: list[SequenceName] = []
    paths: dict[str, Path] = {}
    skipped: list[dict[str, str]] = []
    for path in sorted(motions_dir.glob("*.pkl")):
        try:
            name = parse_sequence_name(path.stem)
        except InputError as exc:
            if options.on_error != "skip":
                raise InputError(exc.problem, path) from None
            skipped.append({"path": str(path), "error": exc.problem})
            continue
        if options.genres and name.genre not in options.genres:
            continue
        if options.exclude_genres and name.genre in options.exclude_genres:
            continue
        if options.situations and name.situation not in options.situations:
            continue
        names.append(name)
        paths[name.seq_id] = path
    if not names:
        raise InputError("no motion pickles to ingest (after --genres/--situations)", motions_dir)
    music_dir = _music_dir(raw, options)
    music_paths: dict[str, Path | None] = {}
    for music_id in sorted({n.music_id for n in names}):
        found = find_music(music_dir, music_id)
        if found is None and not options.allow_missing_music:
            raise InputError(
                f"music {music_id} not found (looked for {music_id}.wav/.flac/.ogg/.mp3); "
                "point --music-dir at the AIST music, or pass --allow-missing-music",
                music_dir,
            )
        music_paths[music_id] = found
    seq_ids = [n.seq_id for n in names]
    cameras = (
        find_camera_inputs(raw, seq_ids, options.on_error)
        if options.wants("cameras")
        else CameraInputs()
    )
    return _Inventory(
        names=names,
        motion_paths=paths,
        music_paths=music_paths,
        split_files=find_split_files(raw),
        ignore_file=find_ignore_list(raw),
        keypoints3d_paths=(
            _annotation_files(raw / "keypoints3d", seq_ids) if options.wants("keypoints3d") else {}
        ),
        keypoints2d_paths=(
            _annotation_files(raw / "keypoints2d", seq_ids) if options.wants("keypoints2d") else {}
        ),
        cameras=cameras,
        skipped=skipped + cameras.skipped,
    )


def _annotation_files(folder: Path, seq_ids: list[str]) -> dict[str, Path]:
    """``{seq_id: folder/<seq_id>.pkl}`` for the pickles present."""
    if not folder.is_dir():
        return {}
    present = {p.stem: p for p in folder.glob("*.pkl")}
    return {seq_id: present[seq_id] for seq_id in seq_ids if seq_id in present}


def _inputs(inventory: _Inventory) -> list[dict[str, Any]]:
    files = list(inventory.motion_paths.values())
    files += list(inventory.keypoints3d_paths.values())
    files += list(inventory.keypoints2d_paths.values())
    files += inventory.cameras.files()
    files += [p for p in inventory.music_paths.values() if p is not None]
    files += list(inventory.split_files.values())
    if inventory.ignore_file is not None:
        files.append(inventory.ignore_file)
    # hashlib releases the GIL on large blocks: threads hash files side by side (same order).
    with ThreadPoolExecutor(max_workers=min(4, os.cpu_count() or 1)) as pool:
        described = pool.map(describe_input, files)
        return list(progress(described, "checksums", total=len(files), unit="file"))


def _music_rows(
    inventory: _Inventory, on_error: str
) -> tuple[list[dict[str, Any]], dict[str, int], dict[str, InputError]]:
    """Music table rows (one per music id with a readable file), each track's feature frame
    count, and — with ``on_error="skip"`` — the unreadable tracks' errors by music id (their
    sequences are skipped too); otherwise an unreadable track raises."""
    rows: list[dict[str, Any]] = []
    frames: dict[str, int] = {}
    unreadable: dict[str, InputError] = {}
    start = 0
    for music_id, path in progress(
        inventory.music_paths.items(), "read music headers", unit="file"
    ):
        if path is None:
            continue
        try:
            info = audio_info(path)
            if info.n_samples == 0:
                raise InputError("music file holds no samples", path)
        except InputError as exc:
            if on_error != "skip":
                raise
            unreadable[music_id] = exc
            continue
        n_frames = feature_frames(resampled_length(info.n_samples, info.sr, AUDIO_SR), AUDIO_HOP)
        frames[music_id] = n_frames
        rows.append(
            {
                "music_id": music_id,
                "genre": music_genre(music_id),
                "bpm": music_bpm(music_id),
                "sr": info.sr,
                "channels": info.channels,
                "n_samples": info.n_samples,
                "duration_s": info.duration_s,
                "frame_start": start,
                "frame_stop": start + n_frames,
                "path": str(path),
                "sha256": None,
                # featurize's fast check that the file is still the one hashed here
                **file_stamp(path).columns(),
            }
        )
        start += n_frames
    return rows, frames, unreadable


def _check_music_length(music_id: str, music_frames: int | None, n_frames: int, path: Path) -> None:
    """Music may end at most MAX_MUSIC_SHORTFALL_FRAMES feature frames before the motion."""
    if music_frames is not None and music_frames < n_frames - MAX_MUSIC_SHORTFALL_FRAMES:
        raise InputError(
            f"music {music_id} gives {music_frames} feature frames "
            f"({music_frames / AIST_FPS:.2f} s) but the motion has "
            f"{n_frames} frames ({n_frames / AIST_FPS:.2f} s)",
            path,
        )


def _used_music(music_rows: list[dict[str, Any]], used: set[str]) -> list[dict[str, Any]]:
    """Music rows of the tracks the stored sequences use, frame ranges re-packed from 0."""
    table = [dict(r) for r in music_rows if r["music_id"] in used]
    start = 0
    for row in table:
        n = row["frame_stop"] - row["frame_start"]
        row["frame_start"], row["frame_stop"] = start, start + n
        start += n
    return table


def _sequence_files(inventory: _Inventory, seq_id: str) -> tuple[str, str | None, str | None]:
    """Motion, keypoints3d and keypoints2d files of one sequence (None where absent)."""
    kp3d = inventory.keypoints3d_paths.get(seq_id)
    kp2d = inventory.keypoints2d_paths.get(seq_id)
    return (
        str(inventory.motion_paths[seq_id]),
        None if kp3d is None else str(kp3d),
        None if kp2d is None else str(kp2d),
    )


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
    writes_empty_music_table = True

    def __init__(self, raw: str | Path, options: AistIngestOptions) -> None:
        self.raw = Path(raw)
        self.options = options
        self.on_error = options.on_error

    # -- before the version opens ----------------------------------------------------------
    def plan(self, checksums: InputChecksums, skips: SkipPolicy) -> IngestPlan:
        if not self.raw.is_dir():
            raise InputError("no such directory", self.raw)
        inventory = self.inventory = _inventory(self.raw, self.options)
        skips.skipped.extend(inventory.skipped)
        inputs = _inputs(inventory)
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
                ReadTask(
                    str(inventory.motion_paths[n.seq_id]), _sequence_files(inventory, n.seq_id)
                )
                for n in inventory.names
            ],
            read=_read_sequence,
            task_kind="sequences",
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
        self.music_rows, self.music_frames, self.unreadable_music = _music_rows(
            self.inventory, self.options.on_error
        )
        for row in self.music_rows:
            row["sha256"] = self.checksums[row["path"]]
        for error in self.unreadable_music.values():
            skips.skipped.append({"path": str(error.path or ""), "error": error.problem})

    # -- records ---------------------------------------------------------------------------
    def array_specs(self, first: SequenceRecord | None = None) -> list[StoredArray]:
        return [
            StoredArray("trans", (3,), np.float32, attrs={"units": "m"}),
            StoredArray("axis_angle", (24, 3), np.float32, attrs={"units": "rad"}),
            *self.stored_annotations,
        ]

    def group_attrs(self) -> dict[str, dict[str, Any]]:
        skeleton = {"name": "smpl24", "joints": list(SMPL_JOINTS), "parents": list(SMPL_PARENTS)}
        return {"motion": {"fps": AIST_FPS, "up_axis": "y", "skeleton": skeleton}}

    def check_task(self, task: ReadTask) -> None:
        name = self.names[task.path]
        if name.music_id in self.unreadable_music:
            bad = self.unreadable_music[name.music_id]
            raise InputError(f"its music {name.music_id} is unreadable ({bad.path})", task.path)

    def accept(self, task: ReadTask, value: Any) -> SequenceRecord:
        name = self.names[task.path]
        seq, keypoints = value
        music_available = self.music_frames.get(name.music_id)
        _check_music_length(name.music_id, music_available, seq.n_frames, Path(task.path))
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
    def music_table(self, records: list[SequenceRecord]) -> MusicTable:
        rows = _used_music(self.music_rows, {r.music_id for r in records if r.music_id})
        return MusicTable(rows, {row["music_id"]: row for row in rows})

    def tables(
        self, records: list[SequenceRecord], music: MusicTable
    ) -> dict[str, list[dict[str, Any]]]:
        present = {r.seq_id for r in records}
        inventory = self.inventory
        splits, self.split_counts = split_rows(
            inventory.split_files, inventory.ignore_file, present
        )
        self.used_settings = {
            r.columns["camera_setting"] for r in records if r.columns["camera_setting"]
        }
        cameras = cameras_table_rows(inventory.cameras, self.used_settings, self.checksums)
        return {"splits": splits, **({"cameras": cameras} if cameras else {})}

    def counts(self, records: list[SequenceRecord], totals: IngestTotals) -> dict[str, Any]:
        return {
            "sequences": totals.sequences,
            "frames": totals.frames,
            "music": totals.music,
            "music_missing": sum(r.music_key is None for r in records),
            "camera_settings": len(self.used_settings),
            "annotations_missing": _annotations_missing(records),
            "skipped": totals.skipped,
            "splits": self.split_counts,
            **totals.read_counts,
        }


def ingest_aist(store: str | Path, raw: str | Path, options: AistIngestOptions) -> CommandResult:
    """Ingest the AIST++ annotation root ``raw`` into a new version of ``store``."""
    return ingest(store, AistSource(raw, options))
