"""Decode the audio track of any container FFmpeg reads (MP4, MOV, MKV, AVI, ...) with PyAV.

PyAV (the ``av`` package, part of the optional ``viz`` extra) ships its own FFmpeg libraries, so
no ``ffmpeg`` program is needed on PATH. Samples come back as float32 in [-1, 1] at the track's
native sample rate, channels first; the first audio stream of the container is the one read.

Errors (no audio stream, undecodable data, PyAV missing) are one :class:`InputError` naming the
file.
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np

from dancedata.errors import InputError

__all__ = ["AV_HINT", "av_available", "decode_audio_track", "has_audio_stream"]

AV_HINT = "pip install 'dancedata[viz]'"


def av_available() -> bool:
    """True when PyAV imports (the ``viz`` extra is installed)."""
    try:
        import av  # noqa: F401
    except ImportError:
        return False
    return True


def _import_av(path: Path, what: str):
    try:
        import av
    except ImportError:
        raise InputError(
            f"{what} needs PyAV, from the optional 'viz' extra ({AV_HINT}), which is not installed",
            path,
        ) from None
    return av


def has_audio_stream(path: str | Path) -> bool:
    """Whether the container holds an audio stream, as FFmpeg (through PyAV) sees it.

    Raises:
        InputError: naming the file, when it is missing, PyAV is absent, or FFmpeg cannot open
            it as a media container.
    """
    path = Path(path)
    if not path.is_file():
        raise InputError("file not found", path)
    av = _import_av(path, "reading a video's audio track")
    try:
        with av.open(str(path)) as container:
            return len(container.streams.audio) > 0
    except av.FFmpegError as exc:
        raise InputError(f"cannot open as a media file ({exc})", path) from None


def decode_audio_track(
    path: str | Path, max_seconds: float | None = None
) -> tuple[np.ndarray, int]:
    """Decode the first audio stream of ``path``: ((channels, n) float32, sample rate in Hz).

    Every frame is converted to planar float (``fltp``) at the stream's own rate and channel
    layout by FFmpeg's resampler, so the samples are exactly the decoder's output. With
    ``max_seconds``, decoding stops after ``ceil(max_seconds × rate)`` samples (bounded memory).

    Raises:
        InputError: naming the file, when it has no audio stream, holds no samples, cannot be
            decoded, or PyAV is not installed.
    """
    path = Path(path)
    if not path.is_file():
        raise InputError("file not found", path)
    av = _import_av(path, "reading a video's audio track")
    chunks: list[np.ndarray] = []
    try:
        with av.open(str(path)) as container:
            if not container.streams.audio:
                raise InputError(
                    "the file has no audio track; give the music with --music FILE", path
                )
            stream = container.streams.audio[0]
            rate = int(stream.codec_context.sample_rate or 0)
            if rate <= 0:
                raise InputError("the audio track reports no sample rate", path)
            limit = None if max_seconds is None else math.ceil(max(max_seconds, 0.0) * rate)
            resampler = av.AudioResampler(format="fltp", rate=rate)
            held = 0
            for frame in container.decode(stream):
                for converted in resampler.resample(frame):
                    chunks.append(converted.to_ndarray())
                    held += chunks[-1].shape[1]
                if limit is not None and held >= limit:
                    break
            else:
                for converted in resampler.resample(None):  # flush
                    chunks.append(converted.to_ndarray())
    except av.FFmpegError as exc:
        raise InputError(f"cannot decode the audio track ({exc})", path) from None
    if not chunks:
        raise InputError("the audio track holds no samples", path)
    channels = {c.shape[0] for c in chunks}
    if len(channels) != 1:
        raise InputError(f"the audio track changes channel count ({sorted(channels)})", path)
    samples = np.concatenate(chunks, axis=1).astype(np.float32, copy=False)
    if max_seconds is not None:
        samples = samples[:, : math.ceil(max(max_seconds, 0.0) * rate)]
    if samples.shape[1] == 0:
        raise InputError("the audio track holds no samples", path)
    return np.ascontiguousarray(samples), rate
