"""The inputs of an AIST++ ingest: settings, which files make up the dataset, their checksums,
and the music (headers only: sample rate, length, feature frame range; featurize decodes it).

:func:`find_inventory` lists the motion pickles (by ``--genres`` / ``--situations``), their
keypoint pickles, cameras, splits, ignore list and music; :func:`describe_inputs` hashes them
all (in threads); :func:`music_rows` reads the music headers for the music table.
"""

from __future__ import annotations

import os
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from dancedata.errors import InputError
from dancedata.ingest.aist.annotations import ANNOTATION_KINDS
from dancedata.ingest.aist.camera_inputs import CameraInputs, find_camera_inputs
from dancedata.io.aist import find_ignore_list, find_split_files
from dancedata.io.aist_names import (
    GENRES,
    SITUATIONS,
    SequenceName,
    music_bpm,
    music_genre,
    parse_sequence_name,
)
from dancedata.io.audio import audio_info, feature_frames, find_music, resampled_length
from dancedata.io.music_file import file_stamp
from dancedata.progress import progress
from dancedata.store.checksums import describe_input

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
class AistInventory:
    names: list[SequenceName]
    motion_paths: dict[str, Path]
    music_paths: dict[str, Path | None]
    split_files: dict[tuple[str, str], Path]
    ignore_file: Path | None
    keypoints3d_paths: dict[str, Path] = field(default_factory=dict)
    keypoints2d_paths: dict[str, Path] = field(default_factory=dict)
    cameras: CameraInputs = field(default_factory=CameraInputs)
    skipped: list[dict[str, str]] = field(default_factory=list)


def music_folder(raw: Path, options: AistIngestOptions) -> Path:
    """The music folder, absolute: the music table records paths featurize opens later, maybe
    from another working directory."""
    if options.music_dir is not None:
        return options.music_dir.resolve()
    for candidate in (raw / "wav", raw / "music", raw / "audio"):
        if candidate.is_dir():
            return candidate.resolve()
    return (raw / "wav").resolve()


def check_selection(options: AistIngestOptions) -> None:
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


def find_inventory(raw: Path, options: AistIngestOptions) -> AistInventory:
    check_selection(options)
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
    music_dir = music_folder(raw, options)
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
    return AistInventory(
        names=names,
        motion_paths=paths,
        music_paths=music_paths,
        split_files=find_split_files(raw),
        ignore_file=find_ignore_list(raw),
        keypoints3d_paths=(
            annotation_files(raw / "keypoints3d", seq_ids) if options.wants("keypoints3d") else {}
        ),
        keypoints2d_paths=(
            annotation_files(raw / "keypoints2d", seq_ids) if options.wants("keypoints2d") else {}
        ),
        cameras=cameras,
        skipped=skipped + cameras.skipped,
    )


def annotation_files(folder: Path, seq_ids: list[str]) -> dict[str, Path]:
    """``{seq_id: folder/<seq_id>.pkl}`` for the pickles present."""
    if not folder.is_dir():
        return {}
    present = {p.stem: p for p in folder.glob("*.pkl")}
    return {seq_id: present[seq_id] for seq_id in seq_ids if seq_id in present}


def describe_inputs(inventory: AistInventory) -> list[dict[str, Any]]:
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


def music_rows(
    inventory: AistInventory, on_error: str
) -> tuple[list[dict[str, Any]], dict[str, int], dict[str, InputError]]:
    """Music table rows (one per music id with a readable file), each track's feature frame
    count, and — with ``on_error="skip"`` — the unreadable tracks' errors by music id (their
    sequences are skipped too); otherwise an unreadable track raises."""
    rows: list[dict[str, Any]] = []
    frames: dict[str, int] = {}
    unreadable: dict[str, InputError] = {}
    start = 0
    present = [(music_id, path) for music_id, path in inventory.music_paths.items() if path]
    # only the files found (--allow-missing-music): no "3/3 file" when none was read
    for music_id, path in progress(present, "read music headers", unit="file") if present else ():
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


def check_music_length(music_id: str, music_frames: int | None, n_frames: int, path: Path) -> None:
    """Music may end at most MAX_MUSIC_SHORTFALL_FRAMES feature frames before the motion."""
    if music_frames is not None and music_frames < n_frames - MAX_MUSIC_SHORTFALL_FRAMES:
        raise InputError(
            f"music {music_id} gives {music_frames} feature frames "
            f"({music_frames / AIST_FPS:.2f} s) but the motion has "
            f"{n_frames} frames ({n_frames / AIST_FPS:.2f} s)",
            path,
        )


def used_music(music_rows: list[dict[str, Any]], used: set[str]) -> list[dict[str, Any]]:
    """Music rows of the tracks the stored sequences use, frame ranges re-packed from 0."""
    table = [dict(r) for r in music_rows if r["music_id"] in used]
    start = 0
    for row in table:
        n = row["frame_stop"] - row["frame_start"]
        row["frame_start"], row["frame_stop"] = start, start + n
        start += n
    return table


def sequence_files(inventory: AistInventory, seq_id: str) -> tuple[str, str | None, str | None]:
    """Motion, keypoints3d and keypoints2d files of one sequence (None where absent)."""
    kp3d = inventory.keypoints3d_paths.get(seq_id)
    kp2d = inventory.keypoints2d_paths.get(seq_id)
    return (
        str(inventory.motion_paths[seq_id]),
        None if kp3d is None else str(kp3d),
        None if kp2d is None else str(kp2d),
    )
