"""The music of a video sequence: a ``--music`` file, else the video's own audio track.

Music is only described here (sample rate, length, tempo); featurize decodes it again at
``fps × 512`` Hz. The music starts with the video: ``audio_offset`` is 0, so feature frame i
(at ``i / fps`` s) meets motion frame i.

Tempo: ``--bpm`` when given, else estimated as ``librosa.beat.beat_track`` does on the music
decoded at :data:`BPM_SR` Hz (hop :data:`BPM_HOP`; :mod:`dancedata.compute.tempo`), printed
with its half and double, and recorded as ``bpm_estimated``.

A video's audio track is decoded with PyAV (the optional ``viz`` extra; it ships its own FFmpeg
libraries, so no ``ffmpeg`` program is needed). Its presence is read from the container
(MP4/MOV/AVI); when the video has (or may have) one and PyAV is missing, the ingest stops with a
line naming the extra and suggesting ``--music FILE`` or ``--no-music``.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from dancedata.compute.audio_features import AudioFeatureConfig
from dancedata.errors import InputError
from dancedata.io.audio import audio_info, feature_frames, load_mono, resampled_length
from dancedata.io.audio_decode import DEFAULT_MAX_AUDIO_SECONDS
from dancedata.io.av_audio import AV_HINT, av_available
from dancedata.io.music_file import FileStamp, file_stamp
from dancedata.io.video_clock import audio_track_present, extract_audio
from dancedata.progress import note

BPM_SR = 22050
BPM_HOP = 512


@dataclass(frozen=True)
class MusicTrack:
    """One music track as the ``music`` table describes it.

    Attributes:
        music_id: file stem (the video's stem for its own audio track).
        path: the file featurize decodes (the video itself for its audio track), as given (a
            string: a track read in a worker is saved between runs without pickle).
        sha256: checksum of ``path``.
        sr: native sample rate in Hz; n_samples: samples per channel; channels.
        bpm: beats per minute; bpm_estimated: True when estimated (no ``--bpm``).
        source: "file" (``--music``) or "video_audio".
        stamp: size and mtime of ``path`` (featurize's fast check that it is unchanged).
    """

    music_id: str
    path: str
    sha256: str
    sr: int
    n_samples: int
    channels: int
    bpm: float
    bpm_estimated: bool
    source: str
    stamp: FileStamp | None = None

    @property
    def duration_s(self) -> float:
        return self.n_samples / self.sr

    def feature_frames(self, fps: float) -> int:
        """Feature frames featurize will compute at ``fps`` (sr = fps × 512, hop 512)."""
        cfg = AudioFeatureConfig(fps=fps)
        return feature_frames(resampled_length(self.n_samples, self.sr, cfg.sr), cfg.hop_length)

    def row(self, genre: str | None, frame_start: int, fps: float) -> dict[str, Any]:
        """The ``music`` table row, feature frames from ``frame_start``."""
        return {
            "music_id": self.music_id,
            "genre": genre,
            "bpm": self.bpm,
            "sr": self.sr,
            "channels": self.channels,
            "n_samples": self.n_samples,
            "duration_s": self.duration_s,
            "frame_start": frame_start,
            "frame_stop": frame_start + self.feature_frames(fps),
            "path": str(Path(self.path).resolve()),  # featurize opens it later, from anywhere
            "sha256": self.sha256,
            "bpm_estimated": self.bpm_estimated,
            "music_source": self.source,
            **(self.stamp.columns() if self.stamp else {}),
        }


def estimate_bpm(y: np.ndarray, sr: int, path: Path) -> float:
    """Tempo of mono ``y`` (float32 at ``sr`` Hz) in beats per minute: the tempo
    ``librosa.beat.beat_track`` returns, without its beat tracker
    (:func:`dancedata.compute.tempo.estimate_tempo`); prints it with its half and double."""
    import librosa

    from dancedata.compute.tempo import estimate_tempo, onset_envelope

    if sr != BPM_SR:
        y = librosa.resample(y, orig_sr=sr, target_sr=BPM_SR)
    estimate = estimate_tempo(onset_envelope(y, BPM_SR, BPM_HOP), BPM_SR, BPM_HOP)
    if not estimate.bpm > 0:
        raise InputError("no tempo found in the music; give it with --bpm", path)
    note(f"tempo of {path}: {estimate.line()}; --bpm B sets it")
    return estimate.bpm


def bpm_method() -> dict[str, Any]:
    """How tempos are estimated, for the manifest config."""
    return {"method": "librosa.beat.beat_track", "sr": BPM_SR, "hop_length": BPM_HOP}


def music_from_file(path: Path, sha256: str, bpm: float | None) -> MusicTrack:
    """Describe a ``--music`` file; estimate its tempo when ``bpm`` is None."""
    stamp = file_stamp(path)
    info = audio_info(path)
    if info.n_samples == 0:
        raise InputError("music file holds no samples", path)
    estimated = bpm is None
    if bpm is None:
        if info.duration_s > DEFAULT_MAX_AUDIO_SECONDS:
            raise InputError(
                f"music is {info.duration_s:.0f} s long; estimating its tempo would decode all "
                f"of it, over the {DEFAULT_MAX_AUDIO_SECONDS:g} s limit: give it with --bpm",
                path,
            )
        bpm = estimate_bpm(load_mono(path, BPM_SR), BPM_SR, path)
    return MusicTrack(
        path.stem,
        str(path),
        sha256,
        info.sr,
        info.n_samples,
        info.channels,
        float(bpm),
        estimated,
        "file",
        stamp,
    )


def music_from_video(video: Path, sha256: str, bpm: float | None) -> MusicTrack | None:
    """Describe ``video``'s own audio track; None when the container says it has none.

    Raises:
        InputError: naming the video, when it has (or may have) an audio track and PyAV (the
            ``viz`` extra) is not installed, or decoding fails on a track the container declares.
    """
    present = audio_track_present(video)
    if present is False:
        return None
    if not av_available():
        has = "has an audio track" if present else "may have an audio track (unknown container)"
        raise InputError(
            f"the video {has}, and decoding it needs PyAV from the optional 'viz' extra, which "
            f"is not installed: {AV_HINT}, or give the music with --music FILE, or pass "
            "--no-music",
            video,
        )
    try:
        samples, sr = extract_audio(video, mono=False)
    except InputError:
        if present is None:
            return None  # the unknown container had no decodable audio after all
        raise
    channels, n_samples = (1, samples.shape[0]) if samples.ndim == 1 else samples.shape
    estimated = bpm is None
    if bpm is None:
        mono = samples if samples.ndim == 1 else samples.mean(axis=0)
        bpm = estimate_bpm(np.ascontiguousarray(mono, np.float32), sr, video)
    return MusicTrack(
        video.stem,
        str(video),
        sha256,
        int(sr),
        int(n_samples),
        int(channels),
        float(bpm),
        estimated,
        "video_audio",
        file_stamp(video),
    )
