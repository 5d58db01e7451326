"""``dancedata featurize`` and ``dancedata segment``."""

from __future__ import annotations

from typing import Annotated, Any

import typer
from dancedata.cli.audio_options import (
    AcceptChangedMusic,
    AudioFamilies,
    CacheDir,
    MaxAudioSeconds,
    UseCache,
    settings_values,
    with_settings_options,
)
from dancedata.cli.common import (
    Dask,
    Json,
    Quiet,
    VersionOpt,
    Wait,
    Workers,
    open_handle,
    report,
    setup,
    split_csv,
)
from dancedata.cli.main import app

from dancedata.featurize.family_settings import AudioSettings, MotionSettings


@app.command()
@with_settings_options({"motion_families": MotionSettings, "audio_families": AudioSettings})
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
            help="Motion families, comma-separated: rotations; positions (FK; SMPL stores: "
            "--smpl-model, else the built-in edge_smpl_offsets skeleton); kinematics (velocity, "
            "acceleration, jerk, motion beats, kinetic features, from positions); angular "
            "(angular velocity, weight effort); "
            "angular_derivatives (angular acceleration and jerk, per joint and summed); laban "
            "(Laban Time, Space and Flow efforts from positions, 1 s windows); geometric "
            "(SMPL-24 only); rotations_from_positions (joint rotations solved from positions, "
            "for pose-only stores). A family whose input arrays the store lacks is reported "
            "absent."
        ),
    ] = "rotations",
    audio: Annotated[bool, typer.Option(help="Compute audio features (once per track).")] = True,
    audio_families: AudioFamilies = None,
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
    **settings: Any,
) -> None:
    """Add motion representations and audio features as a new version: by default FACT
    (onset_env, mfcc, chroma_cens, onset_peaks, beats at fps × 512 Hz, hop 512), per-stem
    features of the offline stems and the NMFD of the drums stem. Per-track audio features
    are cached by content (see `dancedata cache list`)."""
    setup(quiet)
    from dancedata.featurize.featurize import FeaturizeOptions
    from dancedata.featurize.featurize import featurize as run

    smpl_model = settings_values(MotionSettings, settings)["smpl_model"]  # option, else $ENV
    options = FeaturizeOptions(
        motion=motion,
        motion_families=split_csv(motion_families) or [],
        audio=audio,
        representations=split_csv(representations) or [],
        euler_order=euler_order,
        smpl_model=smpl_model,
        version=version,
        wait_for_lock=wait,
        workers=workers,
        dask=dask,
        audio_families=split_csv(audio_families),
        audio_settings=AudioSettings(**settings_values(AudioSettings, settings)),
        use_cache=cache,
        cache_dir=str(cache_dir) if cache_dir else None,
        accept_changed_music=accept_changed_music,
        max_audio_seconds=max_audio_seconds or None,
        resampler=resampler,
    )
    handle = open_handle(store)
    report(run(handle, options), "featurize", as_json, store=handle)


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
    tables: Annotated[
        str,
        typer.Option(
            help="Unit tables, comma-separated: measures (always), beats (every beat of the "
            "tempo grid: frame, index in its measure, downbeat flag), phrases (runs of "
            "--phrase-measures measures)."
        ),
    ] = "measures",
    phrase_measures: Annotated[
        int, typer.Option(min=1, help="Measures per phrase (4 or 8 in most dance music).")
    ] = 4,
    version: VersionOpt = None,
    wait: Wait = False,
    quiet: Quiet = False,
    as_json: Json = False,
) -> None:
    """Write the measures table: frames per measure = 60 / bpm × beats_per_measure × fps,
    complete measures only, as a new version; with --tables also the beats and phrases."""
    setup(quiet)
    from dancedata.featurize.segment import SegmentOptions
    from dancedata.featurize.segment import segment as run

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
        tables=tuple(split_csv(tables) or ["measures"]),
        phrase_measures=phrase_measures,
    )
    handle = open_handle(store)
    result = run(handle, options)
    report(result, "segment", as_json, store=handle)
    if not as_json and not quiet:
        for music_id, track in sorted((result.counts.get("phase") or {}).items()):
            typer.echo(
                f"  {music_id}: downbeat at frame {track['phase_frames']:.2f} "
                f"({track['phase_s']:.3f} s; phase moved from 0 by that much)"
            )
