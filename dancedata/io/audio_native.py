"""Decode a music file at its own sample rate and in its own channels.

Stem separation with OpenUnmix wants what ``openunmix`` itself reads from the file: every channel
at the file's rate (44.1 kHz for most music), not the feature-rate mono mix. This module returns
(channels, samples) float32 with the checks of :mod:`dancedata.io.audio_decode`: libsndfile picks
the decoder from the content, at most ``max_seconds`` from the start are read, in blocks, every
sample checked (NaN, ±Inf, beyond ±:data:`~dancedata.io.audio_decode.MAX_ABS_SAMPLE`) with one
line naming the file; content libsndfile cannot read goes through librosa/audioread by path.
"""

from __future__ import annotations

import math
import warnings
from dataclasses import dataclass
from pathlib import Path
from typing import BinaryIO

import numpy as np

from dancedata.errors import InputError
from dancedata.io.audio_decode import check_samples, checked_blocks


@dataclass(frozen=True)
class NativeAudio:
    """``samples`` (channels, n) float32 at the file's own rate ``sr`` Hz; ``header_samples`` per
    channel as the header gives them (``whole``: every sample was decoded)."""

    samples: np.ndarray
    sr: int
    header_samples: int

    @property
    def channels(self) -> int:
        return int(self.samples.shape[0])

    @property
    def whole(self) -> bool:
        return self.samples.shape[1] >= self.header_samples


def decode_native(
    source: str | Path | BinaryIO,
    *,
    path: str | Path | None = None,
    max_seconds: float | None = None,
) -> NativeAudio:
    """Every channel of ``source`` (a path, or an open binary handle of the file at ``path``) at
    its own rate, at most its first ``max_seconds`` seconds (None: all of it).

    Raises:
        InputError: naming the file, when it cannot be decoded, holds no samples, or holds a
            non-finite or out-of-range sample.
    """
    import soundfile as sf

    name = Path(path) if path is not None else Path(str(source))
    try:
        handle = sf.SoundFile(source)
    except (RuntimeError, sf.LibsndfileError, TypeError, ValueError) as exc:
        if isinstance(source, (str, Path)) or path is not None:
            return _decode_native_librosa(name, max_seconds, exc)
        raise InputError(f"cannot decode audio ({type(exc).__name__}: {exc})", name) from None
    with handle:
        sr, channels, header = int(handle.samplerate), int(handle.channels), int(handle.frames)
        header = max(header, 0)
        limit = header if max_seconds is None else min(header, math.ceil(max(max_seconds, 0) * sr))
        out = np.empty((channels, limit), dtype=np.float32)
        done = 0
        for first, block in checked_blocks(handle, limit, sr, name):
            done = first + block.shape[0]
            out[:, first:done] = block.T
    if done == 0:
        raise InputError("audio file holds no samples", name)
    return NativeAudio(np.ascontiguousarray(out[:, :done]), sr, header)


def _decode_native_librosa(
    path: Path, max_seconds: float | None, first_error: BaseException
) -> NativeAudio:
    import librosa

    if not path.is_file():
        raise InputError("music file not found", path)
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            y, sr = librosa.load(str(path), sr=None, mono=False, duration=max_seconds)
    except Exception as exc:  # audioread/soundfile raise many unrelated types
        text = " ".join(str(exc).split()) or " ".join(str(first_error).split())
        raise InputError(
            "cannot decode audio: the content is not a wav/flac/ogg/mp3 stream this decoder "
            f"reads (whatever the extension), or it is truncated ({type(exc).__name__}: {text})",
            path,
        ) from None
    samples = np.atleast_2d(np.asarray(y, dtype=np.float32))
    if samples.shape[-1] == 0:
        raise InputError("audio file holds no samples", path)
    check_samples(samples.T, 0, int(sr), path)
    header = samples.shape[-1] if max_seconds is None else samples.shape[-1] + 1
    return NativeAudio(np.ascontiguousarray(samples), int(sr), header)
