"""``dancedata featurize`` and ``dancedata segment``."""

from __future__ import annotations

import os
from pathlib import Path
from typing import Annotated

import typer
from dancedata.cli.audio_options import (
    AcceptChangedMusic,
    AudioFamilies,
    CacheDir,
    MaxAudioSeconds,
    NmfdIterations,
    NmfdTemplateFrames,
    Stems,
    StemsMemoryMb,
    StemsModel,
    StemsWeights,
    StftSr,
    TempogramFrames,
    UseCache,
)
from dancedata.cli.common import (
    Dask,
    Json,
    Quiet,
    VersionOpt,
    Wait,
    Workers,
    report,
    setup,
    split_csv,
)
from dancedata.cli.main import app


@app.command()
def featurize(
    store: Annotated[str, typer.Argument(help="Store directory or fsspec URL (s3://...).")],
    representations: Annotated[
        str,
        typer.Option(
            help="Motion representations, comma-separated: rotmat,euler,quat,rot6d (Zhou: first "
            "two columns of R), rot6d_rows (pytorch3d/EDGE: first two rows; not by default)."
        ),
    ] = "rotmat,euler,quat,rot6d",
    euler_order: Annotated[
        str | None,
        typer.Option(
            help="scipy Euler order for every joint: upper case intrinsic, lower case extrinsic. "
            "Default: each joint's own order where the rig has one (BVH), else XYZ."
        ),
    ] = None,
    motion: Annotated[bool, typer.Option(help="Compute motion representations.")] = True,
    motion_families: Annotated[
        str,
        typer.Option(
            help="Motion families, comma-separated: rotations; positions (FK; SMPL stores need "
            "--smpl-model); kinematics (velocity, acceleration, jerk, motion beats, kinetic "
            "features, from positions); angular (angular velocity, weight effort); geometric "
            "(SMPL-24 only). A family whose input arrays the store lacks is reported absent."
        ),
    ] = "rotations",
    smpl_model: Annotated[
        Path | None,
        typer.Option(
            help="SMPL model file (.npz/.pkl) for positions of SMPL stores; not bundled "
            "(licence): get it from https://smpl.is.tue.mpg.de. Default: $DANCEDATA_SMPL_MODEL."
        ),
    ] = None,
    audio: Annotated[bool, typer.Option(help="Compute audio features (once per track).")] = True,
    audio_families: AudioFamilies = None,
    stems: Stems = "offline",
    stems_model: StemsModel = "umxhq",
    stems_weights: StemsWeights = None,
    stems_memory_mb: StemsMemoryMb = 4096.0,
    nmfd_iterations: NmfdIterations = 30,
    nmfd_template_frames: NmfdTemplateFrames = 8,
    stft_sr: StftSr = 16000,
    tempogram_frames: TempogramFrames = 384,
    cache: UseCache = True,
    cache_dir: CacheDir = None,
    accept_changed_music: AcceptChangedMusic = False,
    max_audio_seconds: MaxAudioSeconds = 600.0,
    resampler: Annotated[
        str,
        typer.Option(
            help="librosa res_type of the decode to the feature rate: soxr_hq (librosa >= 0.10's "
            "default), kaiser_best (resampy; librosa < 0.10's default, which FACT-era features "
            "used), kaiser_fast, soxr_vhq/mq/lq/qq, fft, scipy, polyphase. Recorded."
        ),
    ] = "soxr_hq",
    workers: Workers = 1,
    dask: Dask = None,
    version: VersionOpt = None,
    wait: Wait = False,
    quiet: Quiet = False,
    as_json: Json = False,
) -> None:
    """Add motion representations and audio features as a new version: by default FACT
    (onset_env, mfcc, chroma_cens, onset_peaks, beats at fps × 512 Hz, hop 512), per-stem
    features of the offline stems and the NMFD of the drums stem. Per-track audio features
    are cached by content (see `dancedata cache list`)."""
    setup(quiet)
    from dancedata.pipeline.audio_families import AudioSettings
    from dancedata.pipeline.featurize import FeaturizeOptions
    from dancedata.pipeline.featurize import featurize as run

    if smpl_model is not None:  # read by MotionSettings (workers inherit the environment)
        os.environ["DANCEDATA_SMPL_MODEL"] = str(smpl_model.resolve())
    options = FeaturizeOptions(
        motion=motion,
        motion_families=split_csv(motion_families) or [],
        audio=audio,
        representations=split_csv(representations) or [],
        euler_order=euler_order,
        version=version,
        wait_for_lock=wait,
        workers=workers,
        dask=dask,
        audio_families=split_csv(audio_families),
        audio_settings=AudioSettings(
            stems=stems,
            stems_model=stems_model,
            stems_weights=str(stems_weights.resolve()) if stems_weights else None,
            stems_memory_mb=stems_memory_mb,
            nmfd_iterations=nmfd_iterations,
            nmfd_template_frames=nmfd_template_frames,
            stft_sr=stft_sr,
            tempogram_frames=tempogram_frames,
        ),
        use_cache=cache,
        cache_dir=str(cache_dir) if cache_dir else None,
        accept_changed_music=accept_changed_music,
        max_audio_seconds=max_audio_seconds or None,
        resampler=resampler,
    )
    report(run(store, options), "featurize", as_json, store=str(store))


@app.command()
def segment(
    store: Annotated[str, typer.Argument(help="Store directory or fsspec URL (s3://...).")],
    beats_per_measure: Annotated[int, typer.Option(min=1, help="Beats in one measure.")] = 4,
    phase: Annotated[
        str,
        typer.Option(
            help="Downbeat offset in frames (0, the default: every sequence starts on one, as "
            "FACT and the thesis cut), or 'auto': estimated per music track from its onset "
            "strength, tracked beats and chroma (needs featurize; docs/STORE.md)."
        ),
    ] = "0",
    version: VersionOpt = None,
    wait: Wait = False,
    quiet: Quiet = False,
    as_json: Json = False,
) -> None:
    """Write the measures table: frames per measure = 60 / bpm × beats_per_measure × fps,
    complete measures only, as a new version."""
    setup(quiet)
    from dancedata.pipeline.segment import SegmentOptions
    from dancedata.pipeline.segment import segment as run

    phase_auto = phase.strip().lower() == "auto"
    try:
        phase_frames = 0.0 if phase_auto else float(phase)
    except ValueError:
        raise typer.BadParameter(
            f"{phase!r}: a number of frames or 'auto'", param_hint="--phase"
        ) from None
    options = SegmentOptions(
        beats_per_measure=beats_per_measure,
        phase_frames=phase_frames,
        version=version,
        wait_for_lock=wait,
        phase_auto=phase_auto,
    )
    result = run(store, options)
    report(result, "segment", as_json, store=str(store))
    if not as_json and not quiet:
        for music_id, track in sorted((result.counts.get("phase") or {}).items()):
            typer.echo(
                f"  {music_id}: downbeat at frame {track['phase_frames']:.2f} "
                f"({track['phase_s']:.3f} s; phase moved from 0 by that much)"
            )
