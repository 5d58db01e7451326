"""``segment --phase auto``: each sequence's downbeat phase from its music's stored features.

Reads, per music track, the FACT arrays featurize wrote (``audio/onset_env``, ``audio/beats``
and, when present, ``audio/chroma_cens``: one frame per motion frame) and estimates where beat 1
falls (:func:`dancedata.compute.downbeat.estimate_downbeat`). A sequence whose frame 0 is the
track's feature frame ``audio_offset`` starts its measures at
``(track phase − audio_offset) mod frames_per_measure``.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from dancedata.compute.downbeat import estimate_downbeat, sequence_phase
from dancedata.compute.measures import frames_per_measure
from dancedata.errors import StoreError
from dancedata.store.layout import warn_once
from dancedata.store.reader import _VersionReader

REQUIRED_ARRAYS = ("audio/onset_env", "audio/beats")


def downbeat_phases(
    reader: _VersionReader, sequences: list[dict[str, Any]], beats_per_measure: int
) -> tuple[dict[str, float], dict[str, dict[str, Any]]]:
    """(phase in frames per seq_id, estimate per music_id) for the sequences with a BPM.

    Sequences without music (or whose track has no feature frames) keep phase 0, with one
    warning line. Raises StoreError when the version has no onset/beat features at all.
    """
    with_bpm = [s for s in sequences if s.get("bpm") is not None and s["bpm"] > 0]
    if not with_bpm:
        return {}, {}
    missing = [name for name in REQUIRED_ARRAYS if not reader.has_array(name)]
    if missing or not reader.has_table("music"):
        raise StoreError(
            f"--phase auto needs the music features {', '.join(missing) or 'and music table'} "
            f"of version {reader.version}: run `dancedata featurize` (FACT family) first",
            str(reader.path),
        )
    music = {row["music_id"]: row for row in reader.table("music").to_pylist()}
    env_array, beats_array = reader.array("audio/onset_env"), reader.array("audio/beats")
    chroma_array = (
        reader.array("audio/chroma_cens") if reader.has_array("audio/chroma_cens") else None
    )
    tracks: dict[str, dict[str, Any]] = {}
    phases: dict[str, float] = {}
    no_music: list[str] = []
    for seq in with_bpm:
        track = music.get(seq.get("music_id") or "")
        if track is None or seq.get("music_missing") or track["frame_stop"] <= track["frame_start"]:
            no_music.append(seq["seq_id"])
            continue
        bpm, fps = float(seq["bpm"]), float(seq["fps"])
        key = track["music_id"]
        if key not in tracks or tracks[key]["bpm"] != bpm:
            span = slice(int(track["frame_start"]), int(track["frame_stop"]))
            estimate = estimate_downbeat(
                np.asarray(env_array[span]),
                bpm,
                fps,
                beats_per_measure,
                beats=np.asarray(beats_array[span]),
                chroma=None if chroma_array is None else np.asarray(chroma_array[span]),
            )
            tracks[key] = {"bpm": bpm, "fps": fps, **estimate.as_dict()}
        fpm = frames_per_measure(bpm, fps, beats_per_measure)
        phases[seq["seq_id"]] = sequence_phase(
            tracks[key]["phase_frames"], int(seq.get("audio_offset") or 0), fpm
        )
    if no_music:
        warn_once(
            f"segment --phase auto: {len(no_music)} sequences with a BPM have no music features "
            f"and keep phase 0 (e.g. {no_music[0]})"
        )
    for track in tracks.values():
        track["phase_s"] = round(track["phase_frames"] / track["fps"], 6)
    return phases, tracks
