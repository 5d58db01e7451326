"""``dancedata resample``: a store version at another motion frame rate, as a new version.

Every motion array is resampled sequence by sequence by the rule of its kind
(:mod:`dancedata.compute.resample_arrays`: rotations by SLERP, positions, translations and
other floats linearly, motion beats to the nearest frame, codes from the nearest frame); arrays
computed over windows set in frames (Laban efforts) are left out for featurize to recompute.

Frame counts: output frame i sits at i / fps seconds; only times inside a sequence are kept,
``n_out = floor((n_in − 1) · fps_out / fps_in) + 1`` (60 → 20: ``(n − 1) // 3 + 1``).

Audio: the contract puts one audio feature frame on every motion frame (sr = fps × hop,
hop 512), so the music table's frame ranges are recomputed for the new rate
(``1 + ceil(n_samples · sr_new / sr) // 512`` per track) and the audio arrays of the parent are
not carried over: they are recomputed from the music files by ``featurize`` at the new rate,
in the version after this one (:func:`resample` runs it when the parent had audio features).

Tables: ``sequences`` gets the new fps, frame counts and ranges and audio frame counts;
``measures``, ``beats`` and ``phrases``, when present, are recomputed on the tempo grid at the
new rate with the settings of the ``segment`` run that wrote them (a numeric downbeat phase,
in frames, scaled by fps_out / fps_in; so every measure and beat keeps its time and lands on
its nearest frame). ``keyframes`` and ``normalization`` are left out (frame indices and
per-frame statistics of the old rate): run ``keyframes`` / ``stats`` again.
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from dancedata.compute.audio_features import AudioFeatureConfig
from dancedata.compute.resample import decimation_step, resampled_frame_count
from dancedata.compute.resample_arrays import ROTATION_ARRAYS, resample_array, rule_of
from dancedata.errors import InputError
from dancedata.featurize.segment import SegmentOptions, beat_rows, measure_rows, phrase_rows
from dancedata.io.audio import feature_frames, resampled_length
from dancedata.store.arrays import FrameArrayWriter
from dancedata.store.backend import StoreBackend
from dancedata.store.backend_open import make_backend
from dancedata.store.command_result import CommandResult
from dancedata.store.contract import build_table
from dancedata.store.layout import warn_once
from dancedata.store.reader import _VersionReader
from dancedata.store.version_step import DerivedVersion, derive_version
from dancedata.store.writer import base_fingerprint

__all__ = ["MAX_FPS", "ResampleOptions", "check_fps", "resample", "resample_version"]

MAX_FPS = 1000.0
FRAME_RULE = (
    "output frame i at i/fps_out s; times inside the sequence only: "
    "n_out = floor((n_in-1)*fps_out/fps_in)+1; integer ratio k: every k-th frame, exact"
)
RESAMPLERS = {
    "slerp": "rotations: SLERP of unit quaternions (wxyz), shorter arc, neighbouring frames",
    "linear": "positions, translations, other floats: linear between neighbouring frames",
    "nearest_event": "motion beats: each event on output frame floor(j*fps_out/fps_in+0.5)",
    "nearest": "integer codes and masks: nearest source frame floor(position+0.5)",
    "recompute": "windowed features (frames): left out, featurize recomputes them",
}
DROPPED_TABLES = ("keyframes", "normalization")
_MAX_CHAIN = 10_000  # versions walked back to find the segment settings


@dataclass
class ResampleOptions:
    fps: float
    version: str | None = None
    wait_for_lock: bool = False
    # Recompute the parent's audio features (and left-out motion features) at the new rate
    # with featurize, as the next version.
    featurize: bool = True


def check_fps(fps: Any, what: str = "--fps") -> float:
    """The target rate as a float, or InputError: a finite number in (0, MAX_FPS]."""
    try:
        value = float(fps)
    except (TypeError, ValueError):
        raise InputError(f"{what} must be a number of frames per second, got {fps!r}") from None
    if not math.isfinite(value) or value <= 0 or value > MAX_FPS:
        raise InputError(
            f"{what} must be a finite frame rate in (0, {MAX_FPS:g}] frames per second, got {fps!r}"
        )
    return value


def resample(store: str | Path | StoreBackend, options: ResampleOptions) -> CommandResult:
    """Write ``options.version`` (default: the latest) at ``options.fps`` as a new version;
    then, when the parent had audio features or windowed motion features, recompute them with
    featurize at the new rate (one more version; the result names the last one and, under
    ``counts["resample_version"]``, the resampled one)."""
    fps = check_fps(options.fps)
    handle = make_backend(store)  # resolved once: the resample step and the featurize share it
    with derive_version(handle, "resample", options.version, options.wait_for_lock) as step:
        result, todo = _resample_step(step, fps)
    if options.featurize and todo["settings_differ"]:
        warn_once(
            f"resample: {', '.join(todo['settings_differ'])} ran with non-default settings; "
            f"recompute them on {result.version} with `dancedata featurize` and those settings"
        )
    if not options.featurize or not (todo["audio_families"] or todo["motion_families"]):
        return result
    from dancedata.featurize.featurize import FeaturizeOptions, featurize

    feat = featurize(
        handle,
        FeaturizeOptions(
            motion=bool(todo["motion_families"]),
            motion_families=todo["motion_families"],
            representations=todo["representations"],
            audio=bool(todo["audio_families"]),
            audio_families=todo["audio_families"],
            version=result.version,
            wait_for_lock=True,
        ),
    )
    counts = {
        **(feat.counts or {}),
        "resample_version": result.version,
        "resample_created": result.created,
        "resample": result.counts,
    }
    return CommandResult(
        version=feat.version, created=result.created or feat.created, counts=counts
    )


def resample_version(
    store: str | Path | StoreBackend, fps: float, version: str | None = None
) -> CommandResult:
    """:func:`resample` without the featurize step (the resampled version only)."""
    return resample(store, ResampleOptions(fps=fps, version=version, featurize=False))


def _source_fps(reader: _VersionReader, sequences: list[dict[str, Any]]) -> float:
    attrs_fps = reader.group_attrs("motion").get("fps")
    rates = {float(s["fps"]) for s in sequences}
    if len(rates) > 1:
        raise InputError(
            f"version {reader.version} mixes frame rates {sorted(rates)}; resample needs one",
            reader.version,
        )
    fps = rates.pop() if rates else attrs_fps
    if fps is None or not (math.isfinite(float(fps)) and float(fps) > 0):
        raise InputError(f"version {reader.version} records no motion frame rate")
    return float(fps)


def _last_config(
    store: str | Path, reader: _VersionReader, command: str, key: str | None = None
) -> dict[str, Any] | None:
    """The config of the newest ``command`` run in the version's history (walking parents;
    with ``key``, the newest whose config has a truthy ``key``)."""
    current: _VersionReader | None = reader
    for _ in range(_MAX_CHAIN):
        if current is None:
            return None
        manifest = current.manifest
        config = manifest.get("config") or {}
        if manifest.get("command") == command and (key is None or config.get(key)):
            return dict(config)
        parent = manifest.get("parent")
        current = _VersionReader(store, parent) if parent else None
    return None


def _segment_config(store: str | Path, reader: _VersionReader) -> dict[str, Any] | None:
    """The config of the ``segment`` run that wrote the version's measures."""
    return _last_config(store, reader, "segment")


def _feature_families(
    store: str | Path, reader: _VersionReader, left_out: list[str]
) -> dict[str, Any]:
    """What featurize must recompute at the new rate: the audio families of the parent (its
    audio group's ``families``), the motion families whose outputs were left out, and the
    rotation representations the parent holds (rewritten consistently by featurize).
    ``settings_differ`` lists families whose recorded settings are not featurize's defaults:
    those are not recomputed automatically (the command says so)."""
    from dancedata.featurize.family import registered
    from dancedata.featurize.family_settings import AudioSettings, MotionSettings

    audio_families = list(reader.group_attrs("audio").get("families") or [])
    motion_registry = registered("motion")
    motion = sorted(
        name
        for name, family in motion_registry.items()
        if any(f"motion/{spec.path}" in left_out for spec in family.outputs)
    )
    reps = [n for n in ROTATION_ARRAYS if n != "axis_angle" and reader.has_array(f"motion/{n}")]
    differ: list[str] = []
    recorded_audio = (_last_config(store, reader, "featurize", "audio_families") or {}).get(
        "audio_families"
    ) or {}
    audio_registry = registered("audio")
    for name in audio_families:
        if name not in audio_registry or recorded_audio.get(name) != audio_registry[name].config(
            AudioSettings()
        ):
            differ.append(name)
    recorded_motion = (_last_config(store, reader, "featurize", "motion_families") or {}).get(
        "motion_families"
    ) or {}
    settings = MotionSettings(representations=tuple(reps) or ("rotmat",))
    for name in motion:
        if recorded_motion.get(name) != motion_registry[name].config(settings):
            differ.append(name)
    return {
        "audio_families": [n for n in audio_families if n not in differ],
        "motion_families": [n for n in motion if n not in differ],
        "representations": reps,
        "settings_differ": differ,
    }


def _resample_step(step: DerivedVersion, fps: float) -> tuple[CommandResult, dict[str, Any]]:
    reader = step.reader
    sequences = reader.table("sequences").to_pylist()
    if not sequences:
        raise InputError(f"version {step.parent} has no sequences to resample", str(step.store))
    src_fps = _source_fps(reader, sequences)
    if abs(src_fps - fps) <= 1e-9 * src_fps:
        raise InputError(
            f"version {step.parent} is already at {src_fps:g} fps; nothing to resample",
            str(step.store),
        )
    motion_attrs = reader.group_attrs("motion")
    names = sorted(n for n in reader.array_names() if n.startswith("motion/"))
    rules = {n: rule_of(n.split("/", 1)[1], np.dtype(reader.array(n).dtype)) for n in names}
    left_out = [n for n, r in rules.items() if r == "recompute"]
    audio_arrays = sorted(n for n in reader.array_names() if n.startswith("audio/"))
    segment_config = _segment_config(step.store, reader) if reader.has_table("measures") else None
    segment_tables = [t for t in ("measures", "beats", "phrases") if reader.has_table(t)]
    todo = _feature_families(step.store, reader, left_out)
    cfg_new = AudioFeatureConfig(fps=fps)
    config: dict[str, Any] = {
        "source_fps": src_fps,
        "target_fps": fps,
        "frames": FRAME_RULE,
        "decimation_step": decimation_step(src_fps, fps),
        "resampler": {"rotations": "slerp", "positions": "linear", "events": "nearest_event"},
        "rules": {n: rules[n] for n in names},
        "rule_meaning": RESAMPLERS,
        "audio": {
            "rule": "one feature frame per motion frame: recomputed by featurize at the new fps "
            "(sr = fps*hop), never resampled",
            "fps": fps,
            "sr": cfg_new.sr,
            "hop_length": cfg_new.hop_length,
            "left_out": audio_arrays,
            "recompute_families": todo["audio_families"],
            "recompute_by_hand": todo["settings_differ"],
        },
        "left_out_motion": left_out,
        "recompute_motion_families": todo["motion_families"],
        "segment": (
            {"tables": segment_tables, "settings": segment_config}
            if segment_config is not None
            else None
        ),
        "left_out_tables": [t for t in DROPPED_TABLES if reader.has_table(t)],
    }
    fp = step.fingerprint(config, [base_fingerprint(reader.manifest)])
    done = step.already_done(fp)
    if done is not None:
        return done, todo

    began = time.perf_counter()
    music_rows, track_frames = _music_rows(reader, cfg_new)
    new_sequences = _sequence_rows(sequences, src_fps, fps, track_frames)
    _audio_frames(new_sequences, track_frames, src_fps, fps)
    segment = _segment_tables(new_sequences, segment_config, segment_tables, src_fps, fps, step)
    with step.writer(config, fp) as version:
        root = version.zarr_group()
        for name in [*names, *audio_arrays]:
            version.remove_array(name)
        parent_audio = reader.root["audio"] if reader.root and "audio" in reader.root else None
        for sub in list(parent_audio.group_keys()) if parent_audio is not None else []:
            version.remove_array(f"audio/{sub}")
        root = version.zarr_group()
        motion = root.require_group("motion")
        motion.attrs.update({**motion_attrs, "fps": fps})
        audio = root.require_group("audio")
        audio.attrs.clear()
        _write_motion(reader, motion, names, rules, sequences, new_sequences, src_fps, fps)
        version.write_table("sequences", build_table("sequences", new_sequences))
        if music_rows is not None:
            version.write_table("music", build_table("music", music_rows))
        for table, rows in segment.items():
            version.write_table(table, build_table(table, rows))
        for table in DROPPED_TABLES:
            version.remove_table(table)
        counts = {
            "sequences": len(new_sequences),
            "frames_in": int(sum(s["n_frames"] for s in sequences)),
            "frames": int(sum(s["n_frames"] for s in new_sequences)),
            "arrays": {
                rule: sum(r == rule for r in rules.values()) for rule in sorted(set(rules.values()))
            },
            **{table: len(rows) for table, rows in segment.items()},
            "units": 1,
            "resumed_units": 0,
            "seconds": round(time.perf_counter() - began, 3),
        }
        name = version.commit(counts)
    return CommandResult(version=name, created=True, counts=counts), todo


def _sequence_rows(
    sequences: list[dict[str, Any]], src_fps: float, fps: float, track_frames: dict[str, int]
) -> list[dict[str, Any]]:
    """Sequences at the new rate: motion frames by the frame rule; a music-only sequence
    (``source`` ``music``: no motion) keeps its track's feature frames at the new rate."""
    rows, start = [], 0
    for seq in sequences:
        if seq.get("source") == "music" and seq.get("music_id") in track_frames:
            n = track_frames[seq["music_id"]]
        else:
            n = resampled_frame_count(int(seq["n_frames"]), src_fps, fps)
        row = dict(seq)
        row.update(
            fps=fps,
            n_frames=n,
            frame_start=start,
            frame_stop=start + n,
            audio_offset=int(math.floor(int(seq["audio_offset"]) * fps / src_fps + 0.5)),
        )
        rows.append(row)
        start += n
    return rows


def _music_rows(
    reader: _VersionReader, cfg: AudioFeatureConfig
) -> tuple[list[dict[str, Any]] | None, dict[str, int]]:
    """The music table with each track's feature frame range at the new rate."""
    if not reader.has_table("music"):
        return None, {}
    rows = reader.table("music").to_pylist()
    frames: dict[str, int] = {}
    start = 0
    for row in rows:
        n = feature_frames(
            resampled_length(int(row["n_samples"]), int(row["sr"]), cfg.sr), cfg.hop_length
        )
        row["frame_start"], row["frame_stop"] = start, start + n
        frames[row["music_id"]] = n
        start += n
    return rows, frames


def _audio_frames(
    rows: list[dict[str, Any]], track_frames: dict[str, int], src_fps: float, fps: float
) -> None:
    for row in rows:
        available = track_frames.get(row.get("music_id"))
        if available is None:
            if "audio_frames" in row:
                row["audio_frames"] = 0
            continue
        available -= int(row["audio_offset"])
        if "audio_frames" in row:
            row["audio_frames"] = max(0, min(int(row["n_frames"]), available))
        if "audio_truncated_frames" in row:
            row["audio_truncated_frames"] = max(0, available - int(row["n_frames"]))


def _segment_tables(
    sequences: list[dict[str, Any]],
    config: dict[str, Any] | None,
    tables: list[str],
    src_fps: float,
    fps: float,
    step: DerivedVersion,
) -> dict[str, list[dict[str, Any]]]:
    """measures (and beats, phrases) at the new rate, with the parent's segment settings."""
    if not tables:
        return {}
    if config is None:
        raise InputError(
            f"version {step.parent} has a measures table but no segment run in its history; "
            "cannot recompute it at the new rate",
            str(step.store),
        )
    phase = config.get("phase_frames", 0.0)
    phases = None
    options = SegmentOptions(
        beats_per_measure=int(config.get("beats_per_measure", 4)),
        tables=tuple(tables),
        phrase_measures=int(config.get("phrase_measures", 4)),
    )
    if phase == "auto":
        old = step.reader.table("measures").to_pylist()
        phases = {}
        for m in old:
            if "phase_frames" in m and m["phase_frames"] is not None:
                phases.setdefault(m["seq_id"], float(m["phase_frames"]) * fps / src_fps)
    else:
        options.phase_frames = float(phase) * fps / src_fps
    try:
        out = {"measures": measure_rows(sequences, options, phases)}
        if "beats" in tables:
            out["beats"] = beat_rows(sequences, options, phases)
    except ValueError as exc:
        raise InputError(f"{fps:g} fps is too coarse for the tempo grid: {exc}") from None
    if "phrases" in tables:
        out["phrases"] = phrase_rows(sequences, out["measures"], options.phrase_measures)
    return out


def _euler_order(attrs: dict[str, Any]) -> str | list[str] | None:
    order = attrs.get("order")
    return order if isinstance(order, (str, list)) else None


def _write_motion(
    reader: _VersionReader,
    group: Any,
    names: list[str],
    rules: dict[str, str],
    old: list[dict[str, Any]],
    new: list[dict[str, Any]],
    src_fps: float,
    fps: float,
) -> None:
    """Each kept motion array, sequence by sequence (memory: one sequence of one array)."""
    for name in names:
        rule = rules[name]
        if rule == "recompute":
            continue
        source = reader.array(name)
        attrs = dict(source.attrs)
        short = name.split("/", 1)[1]
        writer = FrameArrayWriter(
            group,
            short,
            tuple(source.shape[1:]),
            source.dtype,
            attrs=attrs,
            chunk_frames=int(source.chunks[0]),
        )
        for before, after in zip(old, new, strict=True):
            values = np.asarray(source[int(before["frame_start"]) : int(before["frame_stop"])])
            out = resample_array(
                values, rule, src_fps, fps, ROTATION_ARRAYS.get(short), _euler_order(attrs)
            )
            if out.shape[0] != after["n_frames"]:
                raise AssertionError(f"{name}: {out.shape[0]} frames, expected {after['n_frames']}")
            writer.append(out)
            if short == "keypoints3d" and "keypoints3d_nan_frames" in after:
                # frames with a missing keypoint, counted again at the new rate
                after["keypoints3d_nan_frames"] = int(
                    np.isnan(out.reshape(len(out), -1)).any(1).sum()
                )
        writer.close()
