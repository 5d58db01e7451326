"""``dancedata ingest aist``: AIST++ annotations and music into a new store version.

Streams sequences (motion, keypoints3d, keypoints2d) into frame-concatenated arrays, so memory
is bounded by one read batch (:mod:`dancedata.exec.reads`) and one chunk per array whatever the
dataset size; then writes the sequences, music, cameras and splits tables (a few hundred bytes
per sequence).
Music is only described here (sample rate, length, feature frame range); featurize decodes it.
"""

from __future__ import annotations

import os
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from dancedata._version import __version__
from dancedata.aist_names import (
    GENRES,
    SITUATIONS,
    SequenceName,
    music_bpm,
    music_genre,
    parse_sequence_name,
)
from dancedata.errors import DancedataError, InputError
from dancedata.exec.executors import make_executor
from dancedata.exec.reads import ResumableReads
from dancedata.ingest.aist_annotations import (
    ANNOTATION_KINDS,
    AnnotationWriters,
    SequenceAnnotations,
    read_annotations,
)
from dancedata.ingest.aist_camera_inputs import (
    CameraInputs,
    cameras_table_rows,
    find_camera_inputs,
)
from dancedata.ingest.aist_splits import split_rows
from dancedata.ingest.locked import already_ingested, latest_version
from dancedata.io.aist import AistMotion, find_ignore_list, find_split_files, read_motion
from dancedata.io.audio import audio_info, feature_frames, find_music, resampled_length
from dancedata.io.music_file import file_stamp
from dancedata.progress import progress
from dancedata.smpl import SMPL_JOINTS, SMPL_PARENTS
from dancedata.store.arrays import FrameArrayWriter
from dancedata.store.checksums import describe_input, fingerprint
from dancedata.store.command_result import CommandResult
from dancedata.store.contract import build_table
from dancedata.store.writer import VersionWriter, hold_store_lock

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
    # Processes reading pickles (not fingerprinted: the bytes do not depend on it).
    workers: int = 1

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


def _sequence_row(
    name: SequenceName,
    n_frames: int,
    frame_start: int,
    music_frames: int | None,
    path: str,
    checksums: dict[str, str],
) -> dict[str, Any]:
    """The contract columns of one sequence, and how its music covers it."""
    return {
        "seq_id": name.seq_id,
        "source": "aistpp",
        "genre": name.genre,
        "situation": name.situation,
        "camera": name.camera,
        "dancer": name.dancer,
        "music_id": name.music_id,
        "choreo": name.choreo,
        "bpm": music_bpm(name.music_id),
        "fps": AIST_FPS,
        "n_frames": n_frames,
        "frame_start": frame_start,
        "frame_stop": frame_start + n_frames,
        "audio_offset": 0,
        "audio_frames": 0 if music_frames is None else min(n_frames, music_frames),
        "audio_truncated_frames": 0 if music_frames is None else max(0, music_frames - n_frames),
        "music_missing": music_frames is None,
        "path": path,
        "sha256": checksums[path],
    }


def _used_music(music_rows: list[dict[str, Any]], used: set[str]) -> list[dict[str, Any]]:
    """Music rows of the tracks the stored sequences use, frame ranges re-packed from 0."""
    table = [dict(r) for r in music_rows if r["music_id"] in used]
    start = 0
    for row in table:
        n = row["frame_stop"] - row["frame_start"]
        row["frame_start"], row["frame_stop"] = start, start + n
        start += n
    return table


def _annotations_missing(rows: list[dict[str, Any]]) -> dict[str, int]:
    """Per annotation kind (and music), how many stored sequences lack it."""
    return {
        "keypoints3d": sum(not r["has_keypoints3d"] for r in rows),
        "keypoints2d": sum(not r["has_keypoints2d"] for r in rows),
        "cameras": sum(r["camera_setting"] is None for r in rows),
        "music": sum(bool(r["music_missing"]) for r in rows),
    }


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
    """One resumable read unit item: a sequence's motion and keypoint pickles, checked."""
    motion, kp3d, kp2d = files
    seq = read_motion(motion)
    keypoints = read_annotations(
        None if kp3d is None else Path(kp3d),
        None if kp2d is None else Path(kp2d),
        seq.n_frames,
        AIST_FPS,
    )
    return seq, keypoints


def ingest_aist(store: str | Path, raw: str | Path, options: AistIngestOptions) -> CommandResult:
    """Ingest the AIST++ annotation root ``raw`` into a new version of ``store``."""
    raw = Path(raw)
    if not raw.is_dir():
        raise InputError("no such directory", raw)
    inventory = _inventory(raw, options)
    inputs = _inputs(inventory)
    config = options.config()
    fp = fingerprint("ingest aist", config, [i["sha256"] for i in inputs], __version__)
    ingested = already_ingested(store, fp)  # (asked again under the lock)
    if ingested is not None:
        return ingested
    music_rows, music_frames, unreadable_music = _music_rows(inventory, options.on_error)
    checksums = {i["path"]: i["sha256"] for i in inputs}
    for row in music_rows:
        row["sha256"] = checksums[row["path"]]

    # No lost update: the items below are entered in order, so the parent is read once the
    # lock is held, and the result is looked for again under it (dancedata.ingest.locked).
    with (
        hold_store_lock(store, wait=options.wait_for_lock, create=True) as lock,
        make_executor(options.workers) as executor,
        VersionWriter(
            store,
            command="ingest aist",
            config=config,
            fingerprint=fp,
            inputs=inputs,
            parent=latest_version(store),
            carry_over=False,
            wait_for_lock=options.wait_for_lock,
            stage="ingest",
            resumable=True,
            lock=lock,
        ) as version,
    ):
        ingested = already_ingested(store, fp)  # by a writer this one waited for
        if ingested is not None:
            return ingested
        # resume (issue 8.1): keep the reads a killed run finished, rebuild every output.
        version.reset_outputs()
        version.mark_prepared()
        for item in inventory.skipped:
            version.skip(item["path"], item["error"])
        for error in unreadable_music.values():
            version.skip(error.path or "", error.problem)
        root = version.zarr_group()
        motion = root.require_group("motion")
        root.require_group("audio")
        motion.attrs.update(
            {
                "fps": AIST_FPS,
                "up_axis": "y",
                "skeleton": {
                    "name": "smpl24",
                    "joints": list(SMPL_JOINTS),
                    "parents": list(SMPL_PARENTS),
                },
            }
        )
        trans_writer = FrameArrayWriter(motion, "trans", (3,), np.float32, attrs={"units": "m"})
        aa_writer = FrameArrayWriter(
            motion, "axis_angle", (24, 3), np.float32, attrs={"units": "rad"}
        )
        annotations = AnnotationWriters(
            motion,
            keypoints3d=bool(inventory.keypoints3d_paths),
            keypoints2d=bool(inventory.keypoints2d_paths),
        )
        rows: list[dict[str, Any]] = []
        frame = 0
        reads = ResumableReads(
            version.build_area(),
            "sequences",
            [_sequence_files(inventory, name.seq_id) for name in inventory.names],
            _read_sequence,
            executor=executor,
            desc="read sequences",
        )
        # reads first: it runs the read units (their own bar) before yielding anything
        for loaded, name in zip(
            reads, progress(inventory.names, "ingest sequences", unit="seq"), strict=True
        ):
            path = inventory.motion_paths[name.seq_id]
            try:
                if name.music_id in unreadable_music:
                    bad = unreadable_music[name.music_id]
                    raise InputError(f"its music {name.music_id} is unreadable ({bad.path})", path)
                seq, keypoints = loaded.get()
                music_available = music_frames.get(name.music_id)
                _check_music_length(name.music_id, music_available, seq.n_frames, path)
            except DancedataError as exc:
                if options.on_error != "skip":
                    raise
                version.skip(exc.path or path, exc.problem)
                continue
            trans_writer.append(seq.trans_m)
            aa_writer.append(seq.axis_angle)
            annotation_columns = annotations.append(keypoints, seq.n_frames)
            rows.append(
                _sequence_row(name, seq.n_frames, frame, music_available, str(path), checksums)
                | {"smpl_scaling": seq.scaling, "smpl_loss": seq.loss}
                | {"camera_setting": inventory.cameras.setting_of.get(name.seq_id)}
                | annotation_columns
            )
            frame += seq.n_frames
        trans_writer.close()
        aa_writer.close()
        annotations.close()
        if not rows:
            raise InputError("every motion was skipped; nothing to ingest", raw)
        present = {r["seq_id"] for r in rows}
        splits, split_counts = split_rows(inventory.split_files, inventory.ignore_file, present)
        music_table = _used_music(music_rows, {r["music_id"] for r in rows})
        used_settings = {r["camera_setting"] for r in rows if r["camera_setting"]}
        camera_table = cameras_table_rows(inventory.cameras, used_settings, checksums)
        version.write_table("sequences", build_table("sequences", rows))
        version.write_table("music", build_table("music", music_table))
        version.write_table("splits", build_table("splits", splits))
        if camera_table:
            version.write_table("cameras", build_table("cameras", camera_table))
        counts = {
            "sequences": len(rows),
            "frames": frame,
            "music": len(music_table),
            "music_missing": sum(r["music_missing"] for r in rows),
            "camera_settings": len(used_settings),
            "annotations_missing": _annotations_missing(rows),
            "skipped": len(version.skipped),
            "splits": split_counts,
            **reads.counts(),
        }
        name = version.commit(counts=counts)
        return CommandResult(version=name, created=True, counts=counts, skipped=version.skipped)
