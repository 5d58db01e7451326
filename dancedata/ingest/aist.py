"""``dancedata ingest aist``: AIST++ annotations and music into a new store version.

Streams one sequence at a time into frame-concatenated arrays (memory bounded by one sequence and
one chunk per array), then writes the sequences, music and splits tables. Music is only
described here (sample rate, length, feature frame range); featurize decodes it.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from dancedata._version import __version__
from dancedata.aist_names import SequenceName, music_bpm, music_genre, parse_sequence_name
from dancedata.errors import DancedataError, InputError
from dancedata.ingest.result import CommandResult
from dancedata.io.aist import find_ignore_list, find_split_files, read_motion, read_name_list
from dancedata.io.audio import audio_info, feature_frames, find_music, resampled_length
from dancedata.progress import progress
from dancedata.smpl import SMPL_JOINTS, SMPL_PARENTS
from dancedata.store.arrays import FrameArrayWriter
from dancedata.store.checksums import describe_input, fingerprint
from dancedata.store.contract import build_table
from dancedata.store.layout import StoreLayout
from dancedata.store.writer import VersionWriter, find_version_with_fingerprint

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
    on_error: str = "fail"  # or "skip"
    wait_for_lock: bool = False

    def config(self) -> dict[str, Any]:
        return {
            "fps": AIST_FPS,
            "audio_sr": AUDIO_SR,
            "audio_hop": AUDIO_HOP,
            "allow_missing_music": self.allow_missing_music,
            "genres": sorted(self.genres) if self.genres else None,
            "exclude_genres": sorted(self.exclude_genres) if self.exclude_genres else None,
            "situations": sorted(self.situations) if self.situations else None,
            "on_error": self.on_error,
        }


@dataclass
class _Inventory:
    names: list[SequenceName]
    motion_paths: dict[str, Path]
    music_paths: dict[str, Path | None]
    split_files: dict[tuple[str, str], Path]
    ignore_file: Path | None
    skipped: list[dict[str, str]] = field(default_factory=list)


def _music_dir(raw: Path, options: AistIngestOptions) -> Path:
    if options.music_dir is not None:
        return options.music_dir
    for candidate in (raw / "wav", raw / "music", raw / "audio"):
        if candidate.is_dir():
            return candidate
    return raw / "wav"


def _inventory(raw: Path, options: AistIngestOptions) -> _Inventory:
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
    return _Inventory(
        names=names,
        motion_paths=paths,
        music_paths=music_paths,
        split_files=find_split_files(raw),
        ignore_file=find_ignore_list(raw),
        skipped=skipped,
    )


def _inputs(inventory: _Inventory) -> list[dict[str, Any]]:
    files = list(inventory.motion_paths.values())
    files += [p for p in inventory.music_paths.values() if p is not None]
    files += list(inventory.split_files.values())
    if inventory.ignore_file is not None:
        files.append(inventory.ignore_file)
    return [describe_input(p) for p in progress(files, "checksums", unit="file")]


def _music_rows(inventory: _Inventory) -> tuple[list[dict[str, Any]], dict[str, int]]:
    """Music table rows (one per music id with a file) and each track's feature frame count."""
    rows: list[dict[str, Any]] = []
    frames: dict[str, int] = {}
    start = 0
    for music_id, path in inventory.music_paths.items():
        if path is None:
            continue
        info = audio_info(path)
        if info.n_samples == 0:
            raise InputError("music file holds no samples", path)
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
            }
        )
        start += n_frames
    return rows, frames


def _split_rows(
    inventory: _Inventory, present: set[str]
) -> tuple[list[dict[str, Any]], dict[str, Any]]:
    """Rows of the splits table for the sequences in the store, and listed/usable counts."""
    ignored = set(read_name_list(inventory.ignore_file)) if inventory.ignore_file else set()
    rows: list[dict[str, Any]] = []
    counts: dict[str, Any] = {"ignore_list": len(ignored), "schemes": {}}
    for (scheme, split), path in sorted(inventory.split_files.items()):
        listed = read_name_list(path)
        listed_ignored = [n for n in listed if n in ignored]
        in_store = [n for n in listed if n in present]
        for name in in_store:
            rows.append(
                {
                    "scheme": scheme,
                    "split": "ignored" if name in ignored else split,
                    "listed_split": split,
                    "seq_id": name,
                }
            )
        counts["schemes"].setdefault(scheme, {})[split] = {
            "listed": len(listed),
            "ignored": len(listed_ignored),
            "usable": len(listed) - len(listed_ignored),
            "in_store": len(in_store),
            "missing_from_store": len(listed) - len(in_store),
        }
    return rows, counts


def ingest_aist(store: str | Path, raw: str | Path, options: AistIngestOptions) -> CommandResult:
    """Ingest the AIST++ annotation root ``raw`` into a new version of ``store``."""
    raw = Path(raw)
    if not raw.is_dir():
        raise InputError("no such directory", raw)
    inventory = _inventory(raw, options)
    inputs = _inputs(inventory)
    config = options.config()
    fp = fingerprint("ingest aist", config, [i["sha256"] for i in inputs], __version__)
    existing = find_version_with_fingerprint(store, fp)
    if existing is not None:
        return CommandResult(version=existing, created=False)
    music_rows, music_frames = _music_rows(inventory)
    checksums = {i["path"]: i["sha256"] for i in inputs}
    for row in music_rows:
        row["sha256"] = checksums[row["path"]]

    layout = StoreLayout(store)
    parent = layout.latest() if layout.exists() else None
    with VersionWriter(
        store,
        command="ingest aist",
        config=config,
        fingerprint=fp,
        inputs=inputs,
        parent=parent,
        carry_over=False,
        wait_for_lock=options.wait_for_lock,
        stage="ingest",
    ) as version:
        for item in inventory.skipped:
            version.skip(item["path"], item["error"])
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
        rows: list[dict[str, Any]] = []
        frame = 0
        for name in progress(inventory.names, "ingest motions", unit="seq"):
            path = inventory.motion_paths[name.seq_id]
            try:
                seq = read_motion(path)
                music_available = music_frames.get(name.music_id)
                if music_available is not None and (
                    music_available < seq.n_frames - MAX_MUSIC_SHORTFALL_FRAMES
                ):
                    raise InputError(
                        f"music {name.music_id} gives {music_available} feature frames "
                        f"({music_available / AIST_FPS:.2f} s) but the motion has "
                        f"{seq.n_frames} frames ({seq.n_frames / AIST_FPS:.2f} s)",
                        path,
                    )
            except DancedataError as exc:
                if options.on_error != "skip":
                    raise
                version.skip(path, exc.problem)
                continue
            trans_writer.append(seq.trans_m)
            aa_writer.append(seq.axis_angle)
            audio_frames = 0 if music_available is None else min(seq.n_frames, music_available)
            rows.append(
                {
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
                    "n_frames": seq.n_frames,
                    "frame_start": frame,
                    "frame_stop": frame + seq.n_frames,
                    "audio_offset": 0,
                    "audio_frames": audio_frames,
                    "audio_truncated_frames": (
                        0 if music_available is None else max(0, music_available - seq.n_frames)
                    ),
                    "music_missing": music_available is None,
                    "smpl_scaling": seq.scaling,
                    "smpl_loss": seq.loss,
                    "path": str(path),
                    "sha256": checksums[str(path)],
                }
            )
            frame += seq.n_frames
        trans_writer.close()
        aa_writer.close()
        if not rows:
            raise InputError("every motion was skipped; nothing to ingest", raw)
        present = {r["seq_id"] for r in rows}
        split_rows, split_counts = _split_rows(inventory, present)
        used_music = {r["music_id"] for r in rows}
        music_table = [r for r in music_rows if r["music_id"] in used_music]
        # Re-pack music frame ranges over the tracks actually used.
        start = 0
        for row in music_table:
            n = row["frame_stop"] - row["frame_start"]
            row["frame_start"], row["frame_stop"] = start, start + n
            start += n
        version.write_table("sequences", build_table("sequences", rows))
        version.write_table("music", build_table("music", music_table))
        version.write_table("splits", build_table("splits", split_rows))
        counts = {
            "sequences": len(rows),
            "frames": frame,
            "music": len(music_table),
            "music_missing": sum(r["music_missing"] for r in rows),
            "skipped": len(version.skipped),
            "splits": split_counts,
        }
        name = version.commit(counts=counts)
        return CommandResult(version=name, created=True, counts=counts, skipped=version.skipped)
