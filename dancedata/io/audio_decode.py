"""Decode music to mono float32 with bounded memory and checked samples.

:func:`decode_mono` reads a file (a path or an open binary handle) with libsndfile, which picks
the decoder from the content, never from the extension: a FLAC named ``.wav`` decodes as the
FLAC it is (WAV, FLAC, OGG/Vorbis, MP3 and the other libsndfile formats). Content libsndfile
cannot read falls back to librosa/audioread by path (e.g. a video's AAC track through ffmpeg),
then to PyAV when the ``viz`` extra is installed (no ffmpeg program needed).

Bounded memory: at most ``max_seconds`` from the start are read (``ceil(max_seconds × sr_native)``
frames), in blocks of :data:`BLOCK_FRAMES` frames, each mixed down to mono before the next is
read; so the peak is the mono span plus one block, whatever the file's length or its header's
claims. The mono signal is then resampled exactly as ``librosa.load(path, sr=sr)`` does (the
mean over channels of the float32 samples, then ``librosa.resample`` with ``soxr_hq``): on the
same samples the output is identical to ``librosa.load``.

Checked samples: every block is checked before use. A sample that is NaN or ±Inf, or whose
magnitude passes :data:`MAX_ABS_SAMPLE`, stops the decode with one line naming the file, the
sample, its time and channel. Full scale is ±1 (integer formats cannot leave it); float files
may exceed it a little when clipped, so up to ±1000 (+60 dBFS) is accepted. Past that the file
is not audio at the scale the features assume, and its power spectra would overflow float32
(|X|² reaches (n_fft · x)²): 1e30 would turn into Inf and NaN features.
"""

from __future__ import annotations

import math
import warnings
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path
from typing import BinaryIO

import numpy as np

from dancedata.errors import InputError

# Largest accepted |sample| (linear, full scale 1.0): +60 dBFS.
MAX_ABS_SAMPLE = 1000.0
# Frames read per block (~6 s at 44.1 kHz): bounds the extra memory of the multichannel read.
BLOCK_FRAMES = 1 << 18
RES_TYPE = "soxr_hq"  # librosa.load's default resampler (librosa >= 0.10)
# librosa res_type names featurize --resampler accepts. kaiser_best/kaiser_fast run resampy
# (librosa < 0.10's load default was kaiser_best: what FACT-era features were made with).
RESAMPLERS: tuple[str, ...] = (
    "soxr_hq",
    "soxr_vhq",
    "soxr_mq",
    "soxr_lq",
    "soxr_qq",
    "kaiser_best",
    "kaiser_fast",
    "fft",
    "scipy",
    "polyphase",
)
# Default limit on the seconds of one track decoded at once (featurize --max-audio-seconds; the
# tempo estimate of ingest bvh/video without --bpm). Measured with the default audio families
# (fact, offline stems, nmfd), one process: 10 decoded minutes peak at 2.5 GB RSS (0.5 GB of it
# the interpreter and libraries), about 2 GB more per further 10 minutes.
DEFAULT_MAX_AUDIO_SECONDS = 600.0


@dataclass(frozen=True)
class DecodedAudio:
    """Mono float32 samples at ``sr`` Hz, decoded from the first ``native_samples`` samples
    (per channel) of a file whose native rate is ``native_sr`` Hz and whose header gives
    ``header_samples`` (``whole``: every sample was decoded)."""

    y: np.ndarray
    sr: int
    native_sr: int
    native_samples: int
    header_samples: int
    channels: int

    @property
    def whole(self) -> bool:
        return self.native_samples >= self.header_samples

    @property
    def decoded_s(self) -> float:
        """Seconds of the file decoded, from its start."""
        return self.native_samples / self.native_sr


def decode_mono(
    source: str | Path | BinaryIO,
    sr: int,
    *,
    path: str | Path | None = None,
    max_seconds: float | None = None,
    res_type: str = RES_TYPE,
) -> DecodedAudio:
    """Mono float32 at ``sr`` Hz from ``source`` (a path, or an open binary handle of the file
    at ``path``), at most its first ``max_seconds`` seconds (None: all of it), resampled by
    ``librosa.resample(..., res_type=res_type)`` (one of :data:`RESAMPLERS`).

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
            return _decode_with_librosa(name, sr, max_seconds, res_type)
        raise _undecodable(name, exc) from None
    with handle:
        native_sr = int(handle.samplerate)
        channels = int(handle.channels)
        header = max(int(handle.frames), 0)
        limit = header if max_seconds is None else min(header, _frames(max_seconds, native_sr))
        mono = _read_mono(handle, limit, native_sr, channels, name)
    return DecodedAudio(
        _resample(mono, native_sr, sr, res_type), sr, native_sr, mono.size, header, channels
    )


def _frames(seconds: float, sr: int) -> int:
    return int(math.ceil(max(seconds, 0.0) * sr))


def checked_blocks(handle, limit: int, sr: int, name: Path) -> Iterator[tuple[int, np.ndarray]]:  # noqa: ANN001
    """(first sample, block) for up to ``limit`` frames of an open ``soundfile.SoundFile``, read
    :data:`BLOCK_FRAMES` at a time: (frames, channels) float32 blocks at ``sr`` Hz, every sample
    checked (:func:`check_samples`) before the block is yielded.

    A read error is one InputError naming the file and the sample (and time) it stopped after;
    a header that promised more than the file holds ends the blocks early (the caller keeps what
    is there). Nothing is held beyond the current block."""
    import soundfile as sf

    done = 0
    while done < limit:
        try:
            block = handle.read(
                frames=min(BLOCK_FRAMES, limit - done), dtype="float32", always_2d=True
            )
        except (RuntimeError, sf.LibsndfileError) as exc:
            raise InputError(
                f"cannot decode audio: damaged or truncated after sample {done} "
                f"({done / sr:.3f} s): {' '.join(str(exc).split())}",
                name,
            ) from None
        if block.shape[0] == 0:
            break  # the header promised more than the file holds: keep what is there
        check_samples(block, done, sr, name)
        yield done, block
        done += block.shape[0]


def _read_mono(handle, limit: int, native_sr: int, channels: int, name: Path) -> np.ndarray:  # noqa: ANN001
    """Up to ``limit`` frames, block by block (:func:`checked_blocks`), each mixed down to mono."""
    mono = np.empty(limit, dtype=np.float32)
    done = 0
    for first, block in checked_blocks(handle, limit, native_sr, name):
        done = first + block.shape[0]
        # as librosa.to_mono: the float32 mean over channels (a single channel as is)
        if channels == 1:
            mono[first:done] = block[:, 0]
        elif channels == 2:
            mono[first:done] = stereo_mean(block)
        else:
            mono[first:done] = np.mean(block.T, axis=0)
    if done == 0:
        raise InputError("audio file holds no samples", name)
    return mono[:done]


def stereo_mean(block: np.ndarray) -> np.ndarray:
    """``np.mean(block.T, axis=0)`` of a (frames, 2) float32 block, the same bits at a thirtieth
    of the CPU (numpy reduces each 2-value row in its own call): float32 (0 + left) + right,
    halved; the leading 0 turns -0 + -0 into +0 as numpy's sum does."""
    out = block[:, 0] + np.float32(0.0)
    out += block[:, 1]
    out /= np.float32(2.0)
    return out


def check_samples(block: np.ndarray, first: int, sr: int, name: str | Path) -> None:
    """Raise when ``block`` ((frames, channels) or (frames,), starting at sample ``first``) holds
    a NaN, an Inf or a sample beyond ±:data:`MAX_ABS_SAMPLE`."""
    if block.size == 0:
        return
    peak = float(np.max(np.abs(block)))  # NaN propagates through max
    if peak <= MAX_ABS_SAMPLE:
        return
    values = block.reshape(block.shape[0], -1)
    bad = ~(np.abs(values) <= MAX_ABS_SAMPLE)
    frame, channel = (int(i[0]) for i in np.nonzero(bad))
    value = float(values[frame, channel])
    index = first + frame
    where = f"sample {index} ({index / sr:.3f} s), channel {channel}"
    if not math.isfinite(value):
        raise InputError(
            f"non-finite audio sample ({value}) at {where}: the file holds NaN/Inf, not audio",
            name,
        )
    raise InputError(
        f"out-of-range audio sample ({value:.3g}) at {where}: samples must lie within "
        f"±{MAX_ABS_SAMPLE:g} (full scale is ±1)",
        name,
    )


def _resample(mono: np.ndarray, native_sr: int, sr: int, res_type: str = RES_TYPE) -> np.ndarray:
    if res_type not in RESAMPLERS:
        raise InputError(f"unknown resampler {res_type!r}; choose from {', '.join(RESAMPLERS)}")
    if native_sr == sr:
        return np.ascontiguousarray(mono, dtype=np.float32)
    if res_type.startswith("soxr"):
        # What librosa.resample computes for soxr_* (soxr, then the length fixed to
        # ceil(n · sr / native_sr)), without importing librosa (seconds for a renderer).
        import soxr

        y = soxr.resample(np.asarray(mono), native_sr, sr, quality=res_type)
        n = int(np.ceil(mono.shape[-1] * float(sr) / native_sr))
        y = y[:n] if y.shape[-1] >= n else np.pad(y, (0, n - y.shape[-1]))
        return np.ascontiguousarray(y, dtype=np.float32)
    import librosa

    try:
        y = librosa.resample(mono, orig_sr=native_sr, target_sr=sr, res_type=res_type)
    except ImportError as exc:  # kaiser_*: resampy, a dependency since issue 14
        raise InputError(
            f"resampler {res_type} needs a package that is not installed ({exc}): "
            "pip install resampy"
        ) from None
    return np.ascontiguousarray(y, dtype=np.float32)


def _decode_with_librosa(
    path: Path, sr: int, max_seconds: float | None, res_type: str = RES_TYPE
) -> DecodedAudio:
    """Content libsndfile cannot read (e.g. AAC in a video, through audioread and ffmpeg)."""
    import librosa

    if not path.is_file():
        raise InputError("music file not found", path)
    try:
        # librosa warns (several lines on stderr) when soundfile fails and audioread takes
        # over; the outcome is reported as one line instead.
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            y, native_sr = librosa.load(str(path), sr=None, mono=False, duration=max_seconds)
    except Exception as exc:  # audioread/soundfile raise many unrelated types
        decoded = _decode_with_av(path, max_seconds)
        if decoded is None:
            raise _undecodable(path, exc) from None
        y, native_sr = decoded
    frames = np.atleast_2d(y).T  # (frames, channels)
    if frames.shape[0] == 0:
        raise InputError("audio file holds no samples", path)
    check_samples(frames, 0, int(native_sr), path)
    mono = frames[:, 0] if frames.shape[1] == 1 else np.mean(frames.T, axis=0)
    n = frames.shape[0]
    header = n if max_seconds is None else n + 1  # unknown: a bounded read may have stopped early
    return DecodedAudio(
        _resample(mono.astype(np.float32), int(native_sr), sr, res_type),
        sr,
        int(native_sr),
        n,
        header,
        frames.shape[1],
    )


def _decode_with_av(path: Path, max_seconds: float | None) -> tuple[np.ndarray, int] | None:
    """(channels, n) float32 and the rate of the first audio stream through PyAV (the ``viz``
    extra: a video's own audio track without the ffmpeg program), at most ``max_seconds`` of it;
    None when PyAV is absent or cannot decode it either."""
    from dancedata.io.av_audio import av_available, decode_audio_track

    if not av_available():
        return None
    try:
        return decode_audio_track(path, max_seconds)
    except InputError:
        return None


def _undecodable(path: Path, exc: BaseException) -> InputError:
    text = " ".join(str(exc).split())
    detail = f"{type(exc).__name__}: {text}" if text else type(exc).__name__
    return InputError(
        f"cannot decode audio: the content is not a wav/flac/ogg/mp3 stream this decoder reads "
        f"(whatever the extension), or it is truncated ({detail})",
        path,
    )
