"""``dancedata featurize``: motion representations and audio features into a new version.

Motion is processed in batches of whole consecutive sequences of about one zarr chunk
(CHUNK_FRAMES frames) each, so memory stays bounded, families may look at neighbouring frames,
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
from dancedata.compute.audio_features import AudioFeatureConfig
from dancedata.compute.motion_representations import REPRESENTATIONS
from dancedata.errors import InputError
from dancedata.ingest.result import CommandResult
from dancedata.io.audio import load_mono
from dancedata.pipeline.audio_families import DEFAULT_FAMILIES, FAMILIES, AudioFamily
from dancedata.pipeline.motion_families import (
    BASE_ARRAYS,
    MotionBatch,
    MotionFamily,
    MotionSettings,
)
from dancedata.pipeline.motion_families import DEFAULT_FAMILIES as DEFAULT_MOTION_FAMILIES
from dancedata.pipeline.motion_families import FAMILIES as MOTION_FAMILIES
from dancedata.progress import progress
from dancedata.store.arrays import CHUNK_FRAMES, FrameArrayWriter
from dancedata.store.checksums import fingerprint
from dancedata.store.contract import build_table
from dancedata.store.layout import StoreLayout
from dancedata.store.reader import VersionReader
from dancedata.store.writer import VersionWriter, already_done, base_fingerprint

DEFAULT_EULER_ORDER = "XYZ"


@dataclass
class FeaturizeOptions:
    """Settings of one featurize run. ``config()`` lists the data-changing ones."""

    motion: bool = True
    audio: bool = True
    representations: list[str] = field(default_factory=lambda: list(REPRESENTATIONS))
    # None: each joint's own order from the motion attrs (BVH rigs), else XYZ (intrinsic).
    euler_order: str | None = None
    motion_families: list[str] = field(default_factory=lambda: list(DEFAULT_MOTION_FAMILIES))
    audio_families: list[str] = field(default_factory=lambda: list(DEFAULT_FAMILIES))
    audio_config: AudioFeatureConfig | None = None  # default: derived from the motion fps
    version: str | None = None  # parent version; default latest
    wait_for_lock: bool = False

    def motion_settings(self) -> MotionSettings:
        return MotionSettings(
            representations=tuple(self.representations),
            euler_order=self.euler_order or DEFAULT_EULER_ORDER,
        )

    def config(self, audio_cfg: AudioFeatureConfig | None) -> dict[str, Any]:
        """Settings that change the data; ``euler_order`` must be resolved first."""
        settings = self.motion_settings()
        return {
            "motion": self.motion,
            "motion_families": (
                {n: MOTION_FAMILIES[n].config(settings) for n in sorted(self.motion_families)}
                if self.motion
                else {}
            ),
            "audio": audio_cfg.as_dict() if (self.audio and audio_cfg) else None,
            "audio_families": (
                {name: FAMILIES[name].config() for name in sorted(self.audio_families)}
                if self.audio
                else {}
            ),
        }


def _validate(options: FeaturizeOptions) -> None:
    unknown_motion = sorted(set(options.motion_families) - set(MOTION_FAMILIES))
    if unknown_motion:
        raise InputError(
            f"unknown motion feature family {unknown_motion}; choose from {sorted(MOTION_FAMILIES)}"
        )
    unknown_families = sorted(set(options.audio_families) - set(FAMILIES))
    if unknown_families:
        raise InputError(
            f"unknown audio feature family {unknown_families}; choose from {sorted(FAMILIES)}"
        )
    unknown = sorted(set(options.representations) - set(REPRESENTATIONS))
    if unknown:
        raise InputError(f"unknown representation(s) {unknown}; choose from {REPRESENTATIONS}")
    try:
        from scipy.spatial.transform import Rotation

        if options.euler_order is not None:
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
    motion_attrs = reader.group_attrs("motion")
    fps = float(motion_attrs.get("fps", 60.0))
    if options.euler_order is None:
        options.euler_order = motion_attrs.get("euler_orders") or DEFAULT_EULER_ORDER
    audio_cfg = options.audio_config or AudioFeatureConfig(fps=fps)
    if options.audio and abs(audio_cfg.fps - fps) > 1e-9:
        raise InputError(f"audio fps {audio_cfg.fps} differs from the motion fps {fps}")
    config = options.config(audio_cfg)
    fp = fingerprint("featurize", config, [base_fingerprint(reader.manifest)], __version__)
    existing = already_done(store, fp, reader.manifest, "featurize")
    if existing is not None:
        return CommandResult(version=existing, created=False)

    requested = (
        [MOTION_FAMILIES[name] for name in options.motion_families] if options.motion else []
    )
    motion_families = [
        f for f in requested if all(reader.has_array(f"motion/{r}") for r in f.requires)
    ]
    absent_families = [f for f in requested if f not in motion_families]
    n_joints = _skeleton_joints(reader)
    motion_arrays = [
        f"motion/{spec.path}"
        for family in motion_families
        for spec in family.arrays(n_joints, options.motion_settings())
    ]
    families = [FAMILIES[name] for name in options.audio_families] if options.audio else []
    audio_arrays = [f"audio/{spec.path}" for f in families for spec in f.arrays(audio_cfg)]
    with VersionWriter(
        store,
        command="featurize",
        config=config,
        fingerprint=fp,
        inputs=[{"path": f"{parent}", "bytes": 0, "sha256": reader.manifest["fingerprint"]}],
        parent=parent,
        wait_for_lock=options.wait_for_lock,
        stage="featurize",
        parent_stages=reader.manifest.get("stages"),
    ) as version:
        for name in motion_arrays + audio_arrays:
            version.remove_array(name)
        counts: dict[str, Any] = {}
        if options.motion:
            counts["motion_frames"] = _featurize_motion(
                reader, version, motion_families, options.motion_settings(), n_joints
            )
            counts["motion_absent"] = {
                f.name: f"needs motion/{', motion/'.join(f.requires)}, which this store lacks"
                for f in absent_families
            }
        if options.audio:
            counts.update(_featurize_audio(reader, version, audio_cfg, families))
        name = version.commit(counts=counts)
    return CommandResult(version=name, created=True, counts=counts)


def sequence_batches(
    starts: np.ndarray, stops: np.ndarray, target_frames: int = CHUNK_FRAMES
) -> list[tuple[int, int]]:
    """Group consecutive sequences into batches of whole sequences of about ``target_frames``
    frames: (first sequence index, stop sequence index) pairs covering all sequences."""
    batches: list[tuple[int, int]] = []
    first = 0
    for i in range(len(starts)):
        if stops[i] - starts[first] >= target_frames or i == len(starts) - 1:
            batches.append((first, i + 1))
            first = i + 1
    return batches


def _featurize_motion(
    reader: VersionReader,
    version: VersionWriter,
    families: list[MotionFamily],
    settings: MotionSettings,
    n_joints: int,
) -> int:
    base = {
        name: reader.array(f"motion/{name}")
        for name in BASE_ARRAYS
        if reader.has_array(f"motion/{name}")
    }
    attrs = reader.group_attrs("motion")
    sequences = reader.table("sequences")
    starts = np.asarray(sequences.column("frame_start").to_numpy(), dtype=np.int64)
    stops = np.asarray(sequences.column("frame_stop").to_numpy(), dtype=np.int64)
    group = version.zarr_group()["motion"]
    writers = {
        spec.path: FrameArrayWriter(group, spec.path, spec.row_shape, spec.dtype, attrs=spec.attrs)
        for family in families
        for spec in family.arrays(n_joints, settings)
    }
    needed = sorted({name for family in families for name in family.requires})
    batches = sequence_batches(starts, stops)
    for first, stop in progress(batches, "featurize motion", unit="batch"):
        f0, f1 = int(starts[first]), int(stops[stop - 1])
        batch = MotionBatch(
            arrays={name: np.asarray(base[name][f0:f1], dtype=np.float64) for name in needed},
            bounds=np.stack([starts[first:stop] - f0, stops[first:stop] - f0], axis=1),
            attrs=attrs,
        )
        for family in families:
            for path, values in family.compute(batch, settings).items():
                writers[path].append(values)
    for writer in writers.values():
        writer.close()
    return int(stops[-1]) if len(stops) else 0


def _skeleton_joints(reader: VersionReader) -> int:
    skeleton = reader.group_attrs("motion").get("skeleton") or {}
    return len(skeleton.get("joints", []))


def _featurize_audio(
    reader: VersionReader,
    version: VersionWriter,
    cfg: AudioFeatureConfig,
    families: list[AudioFamily],
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
            "families": [f.name for f in families],
        }
    )
    specs = [spec for family in families for spec in family.arrays(cfg)]
    writers = {
        spec.path: FrameArrayWriter(audio, spec.path, spec.row_shape, spec.dtype, attrs=spec.attrs)
        for spec in specs
    }
    start = 0
    for row in progress(music, "featurize audio", unit="track"):
        y = load_mono(row["path"], cfg.sr)
        features: dict[str, np.ndarray] = {}
        for family in families:
            features.update(family.compute(y, row["bpm"], cfg))
        n = min(values.shape[0] for values in features.values())
        for path, writer in writers.items():
            writer.append(features[path][:n])
        row["frame_start"], row["frame_stop"] = start, start + n
        start += n
    for writer in writers.values():
        writer.close()
    version.write_table("music", build_table("music", music))
    _update_sequence_audio_frames(reader, version, music)
    return {"music_tracks": len(music), "audio_frames": start}


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
