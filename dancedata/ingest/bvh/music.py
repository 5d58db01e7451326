"""The music of a BVH ingest: each paired file described once (tempo estimated when no bpm is
given), and the music table (the version appended to's tracks first, the same audio under
another path sharing one row, music ids made unique)."""

from __future__ import annotations

from typing import Any

from dancedata.errors import InputError
from dancedata.ingest.bvh.inputs import BvhInput
from dancedata.ingest.source import InputChecksums, SkipPolicy
from dancedata.progress import progress


def music_tracks(
    inputs: list[BvhInput], checksums: InputChecksums, skips: SkipPolicy
) -> tuple[list[BvhInput], dict[str, Any]]:
    """Describe each music file once (tempo estimated when no bpm is given)."""
    from dancedata.ingest.video.music import music_from_file

    tracks: dict[str, Any] = {}
    kept = []
    paired = sum(item.music is not None for item in inputs)
    for item in progress(inputs, "read music", total=paired, unit="file") if paired else inputs:
        if item.music is not None and str(item.music) not in tracks:
            try:
                tracks[str(item.music)] = music_from_file(
                    item.music, checksums.sha(item.music), item.bpm
                )
            except InputError as exc:
                skips.fail_or_skip(exc, item.music)
                continue
        kept.append(item)
    return kept, tracks


def music_table_rows(
    parent_music: list[dict[str, Any]], tracks: dict[str, Any], used: list[BvhInput], fps: float
) -> tuple[list[dict[str, Any]], dict[str, dict[str, Any]]]:
    """Parent rows (re-packed from 0) then one row per new track; rows keyed by file path."""
    rows: list[dict[str, Any]] = []
    by_path: dict[str, dict[str, Any]] = {}
    start = 0
    for old in parent_music:
        row = dict(old)
        n = int(row["frame_stop"]) - int(row["frame_start"])
        row["frame_start"], row["frame_stop"] = start, start + n
        start += n
        rows.append(row)
        by_path[str(row["path"])] = row
    by_sha = {row["sha256"]: row for row in rows}
    ids = {row["music_id"] for row in rows}
    for item in used:
        if item.music is None or str(item.music) in by_path:
            continue
        track = tracks[str(item.music)]
        if track.sha256 in by_sha:  # the same audio under another path
            by_path[str(item.music)] = by_sha[track.sha256]
            continue
        row = track.row(item.genre, start, fps)
        if row["music_id"] in ids:
            row["music_id"] = f"{track.music_id}-{track.sha256[:8]}"
        ids.add(row["music_id"])
        start = row["frame_stop"]
        rows.append(row)
        by_path[str(item.music)] = by_sha[track.sha256] = row
    return rows, by_path
