"""Write real media files with PyAV for tests: a video stream plus an audio track."""

from __future__ import annotations

from fractions import Fraction
from pathlib import Path

import numpy as np


def write_video_with_audio(
    path: Path,
    fps: float,
    n_frames: int,
    audio: np.ndarray,
    sr: int,
    audio_codec: str = "aac",
    size: tuple[int, int] = (96, 64),
) -> Path:
    """Encode ``n_frames`` grey frames (mpeg4) and ``audio`` ((channels, n) float32 in [-1, 1])
    with ``audio_codec`` (``aac``; ``pcm_s16le`` for a lossless track in ``.mov``/``.mkv``)."""
    import av

    audio = np.atleast_2d(np.asarray(audio, dtype=np.float32))
    layout = {1: "mono", 2: "stereo"}[audio.shape[0]]
    with av.open(str(path), "w") as out:
        video = out.add_stream("mpeg4", rate=Fraction(fps).limit_denominator(1001))
        video.width, video.height, video.pix_fmt = size[0], size[1], "yuv420p"
        sound = out.add_stream(audio_codec, rate=sr, layout=layout)
        for i in range(n_frames):
            image = np.full((size[1], size[0], 3), (i * 7) % 256, np.uint8)
            frame = av.VideoFrame.from_ndarray(image, format="rgb24")
            frame.pts = i
            for packet in video.encode(frame):
                out.mux(packet)
        for packet in video.encode(None):
            out.mux(packet)
        fmt = "s16" if audio_codec.startswith("pcm_s16") else "fltp"
        block = 1024
        for start in range(0, audio.shape[1], block):
            chunk = audio[:, start : start + block]
            if fmt == "s16":  # packed int16: (1, n × channels), channels interleaved
                pcm = np.clip(np.round(chunk * 32768.0), -32768, 32767).astype(np.int16)
                interleaved = pcm.T.reshape(1, -1)
                frame = av.AudioFrame.from_ndarray(interleaved, format="s16", layout=layout)
            else:
                frame = av.AudioFrame.from_ndarray(
                    np.ascontiguousarray(chunk), format="fltp", layout=layout
                )
            frame.sample_rate = sr
            frame.pts = start
            for packet in sound.encode(frame):
                out.mux(packet)
        for packet in sound.encode(None):
            out.mux(packet)
    return path


def tone(seconds: float, sr: int, channels: int = 2, seed: int = 0) -> np.ndarray:
    """(channels, n) float32: a 440 Hz tone on channel 0, a 660 Hz tone on channel 1, with a
    little noise, at amplitude ≤ 0.5."""
    t = np.arange(int(round(seconds * sr))) / sr
    rng = np.random.default_rng(seed)
    rows = [
        0.4 * np.sin(2 * np.pi * f * t) + 0.05 * rng.standard_normal(t.size)
        for f in (440.0, 660.0)[:channels]
    ]
    return np.asarray(rows, dtype=np.float32)
