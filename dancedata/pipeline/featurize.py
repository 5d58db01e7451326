"""``dancedata featurize``: motion representations and audio features into a new version.

Motion is processed in blocks of one zarr chunk (CHUNK_FRAMES frames), so memory stays bounded
and every output chunk is written once. Audio features are computed once per music track (never
once per sequence) and the music table's frame ranges are rewritten from the actual feature
lengths.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from dancedata._version import __version__
from dancedata.compute.audio_features import FACT_FEATURES, AudioFeatureConfig, fact_features
from dancedata.compute.motion_representations import (
    REPRESENTATIONS,
    continue_quat_signs,
    representation_attrs,
    representations_from_axis_angle,
    row_shape,
)
from dancedata.errors import InputError, StoreError
from dancedata.ingest.result import CommandResult
from dancedata.io.audio import load_mono
from dancedata.progress import progress
from dancedata.store.arrays import CHUNK_FRAMES, FrameArrayWriter
from dancedata.store.checksums import fingerprint
from dancedata.store.contract import build_table
from dancedata.store.layout import StoreLayout
from dancedata.store.reader import VersionReader
from dancedata.store.writer import VersionWriter, already_done

AUDIO_DTYPES = {
    "onset_env": np.float32,
    "mfcc": np.float32,
    "chroma_cens": np.float32,
    "onset_peaks": np.uint8,
    "beats": np.uint8,
}


@dataclass
class FeaturizeOptions:
    """Settings of one featurize run. ``config()`` lists the data-changing ones."""

    motion: bool = True
    audio: bool = True
    representations: list[str] = field(default_factory=lambda: list(REPRESENTATIONS))
    euler_order: str = "XYZ"
    audio_config: AudioFeatureConfig | None = None  # default: derived from the motion fps
    version: str | None = None  # parent version; default latest
    wait_for_lock: bool = False

    def config(self, audio_cfg: AudioFeatureConfig | None) -> dict[str, Any]:
        return {
            "motion": self.motion,
            "representations": sorted(self.representations) if self.motion else [],
            "euler_order": self.euler_order,
            "audio": audio_cfg.as_dict() if (self.audio and audio_cfg) else None,
            "audio_features": list(FACT_FEATURES) if self.audio else [],
        }


def _validate(options: FeaturizeOptions) -> None:
    unknown = sorted(set(options.representations) - set(REPRESENTATIONS))
    if unknown:
        raise InputError(f"unknown representation(s) {unknown}; choose from {REPRESENTATIONS}")
    try:
        from scipy.spatial.transform import Rotation

        Rotation.identity().as_euler(options.euler_order)
    except ValueError:
        raise InputError(
            f"invalid Euler order {options.euler_order!r}: three axes from x, y, z; upper case "
            "intrinsic, lower case extrinsic (e.g. XYZ, zyx)"
        ) from None


def featurize(store: str | Path, options: FeaturizeOptions) -> CommandResult:
    """Compute the requested features from ``options.version`` (default latest) of ``store``."""
    _validate(options)
    layout = StoreLayout(store)
    parent = layout.resolve(options.version)
    reader = VersionReader(store, parent)
    fps = float(reader.group_attrs("motion").get("fps", 60.0))
    audio_cfg = options.audio_config or AudioFeatureConfig(fps=fps)
    if options.audio and abs(audio_cfg.fps - fps) > 1e-9:
        raise InputError(f"audio fps {audio_cfg.fps} differs from the motion fps {fps}")
    config = options.config(audio_cfg)
    fp = fingerprint("featurize", config, [reader.manifest["fingerprint"]], __version__)
    existing = already_done(store, fp, reader.manifest, "featurize", config)
    if existing is not None:
        return CommandResult(version=existing, created=False)

    motion_arrays = [f"motion/{r}" for r in options.representations] if options.motion else []
    audio_arrays = [f"audio/{a}" for a in FACT_FEATURES] if options.audio else []
    with VersionWriter(
        store,
        command="featurize",
        config=config,
        fingerprint=fp,
        inputs=[{"path": f"{parent}", "bytes": 0, "sha256": reader.manifest["fingerprint"]}],
        parent=parent,
        wait_for_lock=options.wait_for_lock,
    ) as version:
        for name in motion_arrays + audio_arrays:
            version.remove_array(name)
        counts: dict[str, Any] = {}
        if options.motion:
            counts["motion_frames"] = _featurize_motion(reader, version, options)
        if options.audio:
            counts.update(_featurize_audio(reader, version, audio_cfg))
        name = version.commit(counts=counts)
    return CommandResult(version=name, created=True, counts=counts)


def _featurize_motion(
    reader: VersionReader, version: VersionWriter, options: FeaturizeOptions
) -> int:
    if not reader.has_array("motion/axis_angle"):
        raise StoreError("no motion/axis_angle to derive rotations from", reader.path)
    source = reader.array("motion/axis_angle")
    n_frames, n_joints = source.shape[0], source.shape[1]
    sequences = reader.table("sequences")
    starts = np.asarray(sequences.column("frame_start").to_numpy(), dtype=np.int64)
    stops = np.asarray(sequences.column("frame_stop").to_numpy(), dtype=np.int64)
    group = version.zarr_group()["motion"]
    writers = {
        name: FrameArrayWriter(
            group,
            name,
            row_shape(name, n_joints),
            np.float32,
            attrs=representation_attrs(name, options.euler_order),
        )
        for name in options.representations
    }
    last_quat: np.ndarray | None = None  # (J, 4) last frame of the previous block
    blocks = range(0, n_frames, CHUNK_FRAMES)
    for b0 in progress(blocks, "featurize motion", total=len(blocks), unit="chunk"):
        b1 = min(b0 + CHUNK_FRAMES, n_frames)
        block = np.asarray(source[b0:b1], dtype=np.float64)
        reps = representations_from_axis_angle(block, options.representations, options.euler_order)
        if "quat" in reps:
            reps["quat"] = _continuous_quat_block(reps["quat"], b0, b1, starts, stops, last_quat)
            last_quat = reps["quat"][-1]
        for name, values in reps.items():
            writers[name].append(values.astype(np.float32))
    for writer in writers.values():
        writer.close()
    return int(n_frames)


def _continuous_quat_block(
    quat: np.ndarray,
    b0: int,
    b1: int,
    starts: np.ndarray,
    stops: np.ndarray,
    last_quat: np.ndarray | None,
) -> np.ndarray:
    """Sign continuity within each sequence's part of the block [b0, b1)."""
    out = quat.copy()
    overlapping = np.nonzero((starts < b1) & (stops > b0))[0]
    for i in overlapping:
        s0, s1 = max(starts[i], b0), min(stops[i], b1)
        previous = last_quat if (starts[i] < b0 and last_quat is not None) else None
        out[s0 - b0 : s1 - b0] = continue_quat_signs(quat[s0 - b0 : s1 - b0], previous)
    return out


def _featurize_audio(
    reader: VersionReader, version: VersionWriter, cfg: AudioFeatureConfig
) -> dict[str, Any]:
    if not reader.has_table("music"):
        return {"music_tracks": 0}
    music = reader.table("music").to_pylist()
    audio = version.zarr_group().require_group("audio")
    audio.attrs.update(
        {
            "fps": cfg.fps,
            "sr": cfg.sr,
            "hop_length": cfg.hop_length,
            "n_fft": cfg.n_fft,
            "recipe": "FACT (AIST++ baselines)",
            "beat_tightness": cfg.beat_tightness,
        }
    )
    writers = {
        name: FrameArrayWriter(audio, name, _audio_row_shape(name, cfg), AUDIO_DTYPES[name])
        for name in FACT_FEATURES
    }
    start = 0
    for row in progress(music, "featurize audio", unit="track"):
        y = load_mono(row["path"], cfg.sr)
        features = fact_features(y, row["bpm"], cfg)
        n = next(iter(features.values())).shape[0]
        for name, values in features.items():
            writers[name].append(values)
        row["frame_start"], row["frame_stop"] = start, start + n
        start += n
    for writer in writers.values():
        writer.close()
    version.write_table("music", build_table("music", music))
    _update_sequence_audio_frames(reader, version, music)
    return {"music_tracks": len(music), "audio_frames": start}


def _audio_row_shape(name: str, cfg: AudioFeatureConfig) -> tuple[int, ...]:
    return {"mfcc": (cfg.n_mfcc,), "chroma_cens": (cfg.n_chroma,)}.get(name, ())


def _update_sequence_audio_frames(
    reader: VersionReader, version: VersionWriter, music: list[dict[str, Any]]
) -> None:
    """Recompute each sequence's usable audio frames from the actual feature lengths."""
    track_frames = {m["music_id"]: m["frame_stop"] - m["frame_start"] for m in music}
    rows = reader.table("sequences").to_pylist()
    for row in rows:
        available = track_frames.get(row.get("music_id"))
        if available is None:
            continue
        available -= int(row["audio_offset"])
        row["audio_frames"] = max(0, min(int(row["n_frames"]), available))
        row["audio_truncated_frames"] = max(0, available - int(row["n_frames"]))
    version.write_table("sequences", build_table("sequences", rows))
