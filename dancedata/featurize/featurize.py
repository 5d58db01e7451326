"""``dancedata featurize``: motion representations and audio features into a new version.

The families come from the registry (:mod:`dancedata.featurize.family`). The motion families of
a run are put in an order where each runs after the families whose outputs it reads, so one run
can compute ``positions`` and, from them, ``kinematics``; a family whose inputs neither the store
nor an earlier family provides is reported absent.

The work is planned on the driver as independent tasks (see
:mod:`dancedata.featurize.tasks`): motion in chunk-aligned batches of whole sequences,
written straight into pre-sized arrays; audio once per music track (never once per sequence),
saved per track and packed in track order afterwards, with the music table's frame ranges
rewritten from the actual feature lengths. Tasks run serially, on ``workers`` local processes
or on a Dask cluster; the bytes written are the same whichever engine runs them.

Resume: the version is built in ``versions/.tmp-<fingerprint[:16]>``; every finished task leaves
a marker, so a run killed part-way is continued by the next run with the same fingerprint, which
redoes only the tasks without a marker. ``counts`` records them as ``units`` and
``resumed_units`` (the manifest's keys).
"""

from __future__ import annotations

import os
from dataclasses import dataclass, field
from functools import partial
from pathlib import Path
from typing import Any

import numpy as np

from dancedata._version import __version__
from dancedata.compute.audio_features import AudioFeatureConfig
from dancedata.compute.motion_representations import KNOWN_REPRESENTATIONS, REPRESENTATIONS
from dancedata.errors import InputError, StoreError
from dancedata.exec.executors import make_executor
from dancedata.exec.tasks import Job, TaskReport, run_tasks
from dancedata.featurize.audio_track import audio_task_counts
from dancedata.featurize.families.audio import default_families, family_problems, group_attrs
from dancedata.featurize.families.motion import DEFAULT_FAMILIES as DEFAULT_MOTION_FAMILIES
from dancedata.featurize.family import ArraySpec, Family, registered, run_order
from dancedata.featurize.family_settings import AudioSettings, MotionSettings
from dancedata.featurize.music_inputs import (
    DEFAULT_MAX_AUDIO_SECONDS,
    MusicInputs,
    check_music_inputs,
)
from dancedata.featurize.tasks import (
    AudioJob,
    AudioTask,
    MotionJob,
    audio_output,
    plan_motion_tasks,
    run_audio_task,  # called through this module: tests patch it to crash a track part-way
    run_motion_task,
)
from dancedata.io.smpl_model import SMPL_MODEL_ENV
from dancedata.store.arrays import CHUNK_FRAMES, FrameArrayWriter, create_checked_array
from dancedata.store.backend import StoreBackend
from dancedata.store.backend_open import make_backend
from dancedata.store.checksums import fingerprint
from dancedata.store.command_result import CommandResult
from dancedata.store.contract import build_table
from dancedata.store.layout import StoreLayout, warn_once
from dancedata.store.reader import _VersionReader
from dancedata.store.writer import (
    VersionWriter,
    already_done,
    base_fingerprint,
    hold_store_lock,
)

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
    audio_families: list[str] | None = None  # None: default_families(audio_settings)
    audio_config: AudioFeatureConfig | None = None  # default: derived from the motion fps
    audio_settings: AudioSettings = field(default_factory=AudioSettings)  # stems, NMFD, ...
    # librosa res_type of the decode to the feature rate (recorded as audio.res_type);
    # kaiser_best reproduces FACT-era (librosa < 0.10) features. Unused with audio_config.
    resampler: str = "soxr_hq"
    # SMPL model file for the positions family (None: the built-in edge_smpl_offsets skeleton),
    # default $DANCEDATA_SMPL_MODEL read once here; it travels to workers inside MotionSettings,
    # i.e. inside every task, not through their environment.
    smpl_model: str | None = field(default_factory=lambda: os.environ.get(SMPL_MODEL_ENV) or None)
    version: str | None = None  # parent version; default latest
    wait_for_lock: bool = False
    # Execution only (never changes the data, so not in config()):
    workers: int = 1  # local worker processes
    dask: str | None = None  # Dask scheduler address, or "local:N"
    task_frames: int = 2 * CHUNK_FRAMES  # target motion frames per task
    use_cache: bool = True  # per-track audio features from/to the feature cache
    # Music inputs (dancedata.featurize.music_inputs): a file changed since ingest is refused
    # unless accepted (then re-hashed and recorded); seconds decoded per track are limited.
    accept_changed_music: bool = False
    max_audio_seconds: float | None = DEFAULT_MAX_AUDIO_SECONDS  # None or 0: no limit
    cache_dir: str | None = None  # default: dancedata.featurize.feature_cache.default_cache_dir()

    def audio_family_names(self) -> list[str]:
        if self.audio_families is None:
            return default_families(self.audio_settings)
        return list(self.audio_families)

    def feature_cache_dir(self) -> str | None:
        """The feature cache folder workers use (absolute), or None with the cache off."""
        if not self.use_cache:
            return None
        from dancedata.featurize.feature_cache import default_cache_dir

        return str(Path(self.cache_dir or default_cache_dir()).expanduser().resolve())

    def motion_settings(self) -> MotionSettings:
        return MotionSettings(
            representations=tuple(self.representations),
            euler_order=self.euler_order or DEFAULT_EULER_ORDER,
            smpl_model=self.smpl_model,
        )

    def config(self, audio_cfg: AudioFeatureConfig | None) -> dict[str, Any]:
        """Settings that change the data; ``euler_order`` must be resolved first."""
        settings = self.motion_settings()
        motion, audio = registered("motion"), registered("audio")
        return {
            "motion": self.motion,
            "motion_families": (
                {n: motion[n].config(settings) for n in sorted(self.motion_families)}
                if self.motion
                else {}
            ),
            "audio": audio_cfg.as_dict() if (self.audio and audio_cfg) else None,
            "audio_families": (
                {
                    name: audio[name].config(self.audio_settings)
                    for name in sorted(self.audio_family_names())
                }
                if self.audio
                else {}
            ),
        }


def _validate(options: FeaturizeOptions) -> None:
    motion_families = registered("motion")
    unknown_motion = sorted(set(options.motion_families) - set(motion_families))
    if unknown_motion:
        raise InputError(
            f"unknown motion feature family {unknown_motion}; choose from {sorted(motion_families)}"
        )
    if options.audio:
        problems = family_problems(options.audio_family_names(), options.audio_settings)
        if problems:
            raise InputError("; ".join(problems))
    from dancedata.io.audio_decode import RESAMPLERS

    if options.resampler not in RESAMPLERS:
        raise InputError(
            f"unknown resampler {options.resampler!r}; choose from {', '.join(RESAMPLERS)}"
        )
    unknown = sorted(set(options.representations) - set(KNOWN_REPRESENTATIONS))
    if unknown:
        raise InputError(
            f"unknown representation(s) {unknown}; choose from {KNOWN_REPRESENTATIONS}"
        )
    try:
        from scipy.spatial.transform import Rotation

        if options.euler_order is not None:
            Rotation.identity().as_euler(options.euler_order)
    except ValueError:
        raise InputError(
            f"invalid Euler order {options.euler_order!r}: three axes from x, y, z; upper case "
            "intrinsic, lower case extrinsic (e.g. XYZ, zyx)"
        ) from None


def featurize(store: str | Path | StoreBackend, options: FeaturizeOptions) -> CommandResult:
    """Compute the requested features from ``options.version`` (default latest) of ``store``."""
    _validate(options)
    handle = make_backend(store)  # resolved once: lock, reader, writer and tasks share it
    # Parent, fingerprint and the "already done" check are read under the lock: a run that
    # waited behind another writer derives from (or finds) that writer's result.
    with hold_store_lock(handle, wait=options.wait_for_lock) as lock:
        return _featurize_locked(handle, options, lock)


def _featurize_locked(store: StoreBackend, options: FeaturizeOptions, lock: Any) -> CommandResult:
    layout = StoreLayout(store)
    parent = layout.resolve(options.version)
    reader = _VersionReader(layout, parent)
    motion_attrs = reader.group_attrs("motion")
    fps = float(motion_attrs.get("fps", 60.0))
    if options.euler_order is None:
        options.euler_order = motion_attrs.get("euler_orders") or DEFAULT_EULER_ORDER
    audio_cfg = options.audio_config or AudioFeatureConfig(fps=fps, res_type=options.resampler)
    if options.audio and abs(audio_cfg.fps - fps) > 1e-9:
        raise InputError(f"audio fps {audio_cfg.fps} differs from the motion fps {fps}")
    config = options.config(audio_cfg)
    music_inputs = _music_inputs(reader, audio_cfg, options)  # verified before use
    config.update(music_inputs.config())  # accepted changed music: new hashes, new fingerprint
    fp = fingerprint("featurize", config, [base_fingerprint(reader.manifest)], __version__)
    existing = already_done(store, fp, reader.manifest, "featurize")
    if existing is not None:
        return CommandResult(version=existing, created=False)

    n_joints = _skeleton_joints(reader)
    settings = options.motion_settings()
    plan = _plan_motion(reader, options, n_joints, settings)
    motion_families, absent_families, motion_specs = plan.families, plan.absent, plan.specs
    audio_registry = registered("audio")
    families = (
        [audio_registry[name] for name in options.audio_family_names()] if options.audio else []
    )
    audio_specs = [spec for f in families for spec in f.arrays(audio_cfg, options.audio_settings)]
    check_work(options, bool(motion_specs), bool(audio_specs), bool(music_inputs.rows), store)
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
        resumable=True,
        lock=lock,
    ) as version:
        sequences = reader.table("sequences")
        starts = np.asarray(sequences.column("frame_start").to_numpy(), dtype=np.int64)
        stops = np.asarray(sequences.column("frame_stop").to_numpy(), dtype=np.int64)
        music = music_inputs.rows
        if not version.resumed:
            _prepare(version, motion_specs, audio_specs, int(stops[-1]) if len(stops) else 0)
        build = version.build_area()
        store_id = _store_id(store)
        jobs: list[Job] = []
        if motion_specs:
            motion_job = MotionJob(
                store=store_id,
                parent=parent,
                parent_fingerprint=reader.manifest["fingerprint"],
                build=build,
                families=tuple(f.name for f in motion_families),
                settings=settings,
                needed=plan.needed,
                handed_on=plan.handed_on,
            )
            tasks = plan_motion_tasks(starts, stops, CHUNK_FRAMES, options.task_frames)
            jobs.append(
                Job("motion", partial(run_motion_task, motion_job), "featurize motion", tasks)
            )
        audio_tasks = [
            AudioTask(i, row["music_id"], t.path, row["bpm"], t.sha256, t.span_s, t.partial)
            for i, (row, t) in enumerate(zip(music, music_inputs.tracks, strict=True))
        ]
        audio_job = AudioJob(
            build=build,
            families=tuple(f.name for f in families),
            cfg=audio_cfg,
            outputs=tuple(spec.path for spec in audio_specs),
            settings=options.audio_settings,
            cache_dir=options.feature_cache_dir(),
        )
        if audio_specs:
            jobs.append(
                Job(
                    "audio",
                    partial(run_audio_task, audio_job),
                    "featurize audio",
                    audio_tasks,
                    "track",
                )
            )
        with make_executor(options.workers, options.dask) as executor:
            # Tracks first: they are the long tasks, so short motion tasks fill the tail.
            report = run_tasks(build, sorted(jobs, key=lambda j: j.kind != "audio"), executor)
            engine = executor.describe()
        counts: dict[str, Any] = {
            "units": report.tasks,
            "resumed_units": report.resumed,
            "engine": engine,
            "unit_timing": report.timing(),
        }
        if options.motion:
            counts["motion_frames"] = int(stops[-1]) if len(stops) else 0
            counts["motion_absent"] = {
                f.name: f"needs motion/{', motion/'.join(f.requires)}, which this store lacks"
                for f in absent_families
            }
        if options.audio:
            counts.update(
                _pack_audio(reader, version, audio_cfg, audio_job, audio_tasks, music, report)
            )
        name = version.commit(counts=counts)
    return CommandResult(version=name, created=True, counts=counts)


def check_work(
    options: FeaturizeOptions,
    motion: bool,
    audio: bool,
    music: bool,
    store: str | Path | StoreBackend,
) -> None:
    """Loud, not empty: a StoreError (nothing written) when this run would compute no array
    (``motion``/``audio``: arrays planned; ``music``: the store has tracks), and a one-line
    warning when audio features were asked for but the store has no music."""
    if audio and not music and motion:
        warn_once(f"featurize: {store} has no music, so no audio features are computed")
    if motion or (audio and music):
        return
    reasons = []
    if not options.motion:
        reasons.append("motion is off (--no-motion)")
    elif options.motion_families:
        reasons.append(
            f"the motion families {', '.join(options.motion_families)} need arrays this store lacks"
        )
    else:
        reasons.append("no motion family was asked for")
    if not options.audio:
        reasons.append("audio is off (--no-audio)")
    elif not music:
        reasons.append("the store has no music")
    else:
        reasons.append("no audio family was asked for")
    raise StoreError(f"featurize computes nothing, nothing written: {'; '.join(reasons)}", store)


def _music_inputs(
    reader: _VersionReader, cfg: AudioFeatureConfig, options: FeaturizeOptions
) -> MusicInputs:
    """The parent's music rows, each file verified against what ingest recorded and its decoded
    span planned and limited (none when audio is off)."""
    if not options.audio or not reader.has_table("music"):
        return MusicInputs()
    return check_music_inputs(
        reader.table("music").to_pylist(),
        reader.table("sequences").to_pylist(),
        cfg,
        accept_changed=options.accept_changed_music,
        max_audio_seconds=options.max_audio_seconds,
    )


def _store_id(store: StoreBackend) -> str:
    """The store as workers must name it (they reopen it from this string): a URL, or an
    absolute local path."""
    return store.locator()


def _prepare(
    version: VersionWriter,
    motion_specs: list[ArraySpec],
    audio_specs: list[ArraySpec],
    n_frames: int,
) -> None:
    """Replace the carried-over arrays this run recomputes and pre-size the motion arrays
    (tasks write their chunks into them); then mark the build prepared for a resumed run."""
    for spec in motion_specs:
        version.remove_array(f"motion/{spec.path}")
    for spec in audio_specs:
        version.remove_array(f"audio/{spec.path}")
    group = version.zarr_group().require_group("motion")
    for spec in motion_specs:
        array = create_checked_array(  # crc32c codec; tasks write every chunk
            group,
            spec.path,
            shape=(n_frames, *spec.row_shape),
            chunks=(CHUNK_FRAMES, *spec.row_shape),
            dtype=spec.dtype,
        )
        if spec.attrs:
            array.attrs.update(spec.attrs)
    version.mark_prepared({"motion_frames": n_frames})


@dataclass(frozen=True)
class MotionPlan:
    """The motion families of a run in the order they run, the ones absent (an input neither
    the store nor an earlier family provides), their arrays, the arrays read from the store
    and the outputs handed on to a later family of the run."""

    families: list[Family]
    absent: list[Family]
    specs: list[ArraySpec]
    needed: tuple[str, ...]
    handed_on: tuple[str, ...]


def _plan_motion(
    reader: _VersionReader, options: FeaturizeOptions, n_joints: int, settings: MotionSettings
) -> MotionPlan:
    if not options.motion:
        return MotionPlan([], [], [], (), ())
    registry = registered("motion")
    requested = [registry[name] for name in options.motion_families]
    outputs = {f.name: f.arrays(n_joints, settings) for f in requested}
    ordered = run_order(requested, lambda f: [s.path for s in outputs[f.name]])
    runnable: list[Family] = []
    produced: set[str] = set()
    needed: set[str] = set()
    handed_on: set[str] = set()
    for family in ordered:
        if not all(r in produced or reader.has_array(f"motion/{r}") for r in family.requires):
            continue
        for path in (*family.requires, *family.reads_if_present):
            if path in produced:
                handed_on.add(path)
            elif reader.has_array(f"motion/{path}"):
                needed.add(path)
        runnable.append(family)
        produced.update(s.path for s in outputs[family.name])
    absent = [f for f in requested if f not in runnable]
    specs = [s for f in runnable for s in outputs[f.name]]
    return MotionPlan(runnable, absent, specs, tuple(sorted(needed)), tuple(sorted(handed_on)))


def _skeleton_joints(reader: _VersionReader) -> int:
    skeleton = reader.group_attrs("motion").get("skeleton") or {}
    return len(skeleton.get("joints", []))


def _pack_audio(
    reader: _VersionReader,
    version: VersionWriter,
    cfg: AudioFeatureConfig,
    job: AudioJob,
    tasks: list[AudioTask],
    music: list[dict[str, Any]],
    report: TaskReport,
) -> dict[str, Any]:
    """Concatenate the tracks' saved features in music-table order into the audio arrays
    (one streaming writer per array, each chunk written once) and rewrite the music table's
    frame ranges from the actual feature lengths."""
    if not music:
        return {"music_tracks": 0}
    audio = version.zarr_group().require_group("audio")
    audio.attrs.update(
        {
            "fps": cfg.fps,
            "sr": cfg.sr,
            "hop_length": cfg.hop_length,
            "n_fft": cfg.n_fft,
            "families": list(job.families),
        }
    )
    registry = registered("audio")
    specs = [spec for name in job.families for spec in registry[name].arrays(cfg, job.settings)]
    groups = group_attrs(job.families, cfg, job.settings)  # e.g. audio/stems: written whole
    for path in [*groups, *(spec.path for spec in specs)]:
        version.remove_array(f"audio/{path}")  # a pack cut short by a kill starts over
    audio = version.zarr_group().require_group("audio")
    for group, attrs in groups.items():
        audio.require_group(group).attrs.update(attrs)
    writers = {
        spec.path: FrameArrayWriter(audio, spec.path, spec.row_shape, spec.dtype, attrs=spec.attrs)
        for spec in specs
    }
    start = 0
    for task, row in zip(tasks, music, strict=True):
        n = int(report.results[f"audio/{task.id}"]["frames"])
        for path, writer in writers.items():
            writer.append(job.build.load_array(audio_output(task, path)))
        row["frame_start"], row["frame_stop"] = start, start + n
        start += n
    for writer in writers.values():
        writer.close()
    version.write_table("music", build_table("music", music))
    _update_sequence_audio_frames(reader, version, music)
    stats = audio_task_counts([report.results[f"audio/{task.id}"] for task in tasks])
    return {"music_tracks": len(music), "audio_frames": start, **stats}


def _update_sequence_audio_frames(
    reader: _VersionReader, version: VersionWriter, music: list[dict[str, Any]]
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
