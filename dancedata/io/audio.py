"""Decode music files (wav, flac, ogg via soundfile; mp3 and others via librosa/audioread).

Returns mono float32 at a requested sample rate. Decoding errors become one InputError line.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from dancedata.errors import InputError

MUSIC_EXTENSIONS: tuple[str, ...] = (".wav", ".flac", ".ogg", ".mp3")


@dataclass(frozen=True)
class AudioInfo:
    """What a music file holds, read from its header (or by decoding when there is none)."""

    sr: int
    n_samples: int
    channels: int

    @property
    def duration_s(self) -> float:
        return self.n_samples / self.sr


def audio_info(path: str | Path) -> AudioInfo:
    """Sample rate, length in samples and channel count of a music file."""
    import soundfile as sf

    path = Path(path)
    if not path.is_file():
        raise InputError("music file not found", path)
    try:
        info = sf.info(str(path))
        return AudioInfo(
            sr=int(info.samplerate), n_samples=int(info.frames), channels=info.channels
        )
    except (RuntimeError, sf.LibsndfileError):
        pass
    # Content libsndfile cannot read (e.g. AAC through audioread): its exact length needs a
    # decode, bounded by the decode limit so a hostile file cannot take the memory.
    from dancedata.io.audio_decode import DEFAULT_MAX_AUDIO_SECONDS

    bound = DEFAULT_MAX_AUDIO_SECONDS + 1.0
    y, sr = _decode_with_librosa(path, sr=None, mono=False, duration=bound)
    if y.shape[-1] >= int(bound * sr) - 1:
        raise InputError(
            f"music lasts more than {DEFAULT_MAX_AUDIO_SECONDS:g} s in a format only the fallback "
            "decoder reads (knowing its length means decoding it all): convert it to wav or flac",
            path,
        )
    channels = 1 if y.ndim == 1 else y.shape[0]
    return AudioInfo(sr=int(sr), n_samples=int(y.shape[-1]), channels=channels)


def _decode_with_librosa(
    path: Path, sr: int | None, mono: bool, duration: float | None = None
) -> tuple[np.ndarray, int]:
    import warnings

    import librosa

    try:
        # librosa warns (several lines on stderr) when soundfile fails and audioread takes over;
        # the outcome is reported below as one line instead.
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            y, out_sr = librosa.load(str(path), sr=sr, mono=mono, duration=duration)
    except Exception as exc:  # audioread/soundfile raise many unrelated types
        text = " ".join(str(exc).split())
        detail = f"{type(exc).__name__}: {text}" if text else type(exc).__name__
        raise InputError(
            "cannot decode audio: the content is not a wav/flac/ogg/mp3 stream this decoder "
            f"reads (whatever the extension), or it is truncated ({detail})",
            path,
        ) from None
    if y.size == 0:
        raise InputError("audio file holds no samples", path)
    return y, int(out_sr)


def load_mono(path: str | Path, sr: int, max_seconds: float | None = None) -> np.ndarray:
    """Decode ``path`` (at most its first ``max_seconds`` s) to mono float32 resampled to
    ``sr`` Hz, with the numbers of librosa.load (soxr_hq) and every sample checked; see
    :func:`dancedata.io.audio_decode.decode_mono`."""
    from dancedata.io.audio_decode import decode_mono

    path = Path(path)
    if not path.is_file():
        raise InputError("music file not found", path)
    return decode_mono(path, sr, max_seconds=max_seconds).y


def resampled_length(n_samples: int, sr_in: int, sr_out: int) -> int:
    """Samples after resampling, as librosa.resample fixes it: ceil(n × sr_out / sr_in)."""
    if sr_in == sr_out:
        return n_samples
    return int(math.ceil(n_samples * sr_out / sr_in))


def feature_frames(n_samples: int, hop_length: int) -> int:
    """Frames of a centred librosa feature: 1 + n_samples // hop_length."""
    return 1 + n_samples // hop_length


def find_music(music_dir: Path, music_id: str) -> Path | None:
    """``music_dir/<music_id>.<ext>`` for the first extension present, else None."""
    for ext in MUSIC_EXTENSIONS:
        candidate = music_dir / f"{music_id}{ext}"
        if candidate.is_file():
            return candidate
    return None
