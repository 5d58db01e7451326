"""Encode frames and music into an MP4 with PyAV (its own FFmpeg: no system ffmpeg needed).

Video: H.264 (``libx264``, preset ``ultrafast``: on skeleton drawings at CRF 20 about half the
encoder CPU time of ``superfast``, for files about 1.5 times larger) in yuv420p, frames
converted from BGR by OpenCV, or MPEG-4 part 2 when the
PyAV build has no libx264; frame i has pts i in a time base of 1 / fps, so the stream's frame
rate is the sequence's exactly (as a fraction: 30000/1001 for 29.97 fps). Audio: AAC, mono, at
:data:`AUDIO_SR` Hz, interleaved with the video as it is written so that players start both
together. The output is written to a temporary name next to ``out`` and renamed when complete.
"""

from __future__ import annotations

import os
from fractions import Fraction
from pathlib import Path

import numpy as np

from dancedata.errors import InputError

__all__ = ["AUDIO_SR", "VideoWriter", "frame_rate", "video_codec"]

AUDIO_SR = 48000
AUDIO_BLOCK = 1024  # samples per audio frame handed to the AAC encoder
PRESET = "ultrafast"  # libx264 preset (module docstring)


def frame_rate(fps: float) -> Fraction:
    """``fps`` as the fraction the container records (denominator ≤ 1001)."""
    if not fps > 0:
        raise InputError(f"frame rate must be positive, not {fps}")
    return Fraction(fps).limit_denominator(1001)


def video_codec() -> str:
    """``libx264`` when this PyAV build has the encoder, else ``mpeg4``."""
    import av

    try:
        av.codec.Codec("libx264", "w")
    except Exception:  # noqa: BLE001 - any failure to find the encoder means: not available
        return "mpeg4"
    return "libx264"


def bgr_to_i420(image: np.ndarray) -> np.ndarray:
    """(H * 3 / 2, W) uint8 I420 planes of a BGR (H, W, 3) uint8 image, a new array.

    OpenCV's BGR → I420 (BT.601, limited range, as swscale's default) is a third of the cost of
    handing bgr24 frames to PyAV's converter."""
    import cv2

    return cv2.cvtColor(image, cv2.COLOR_BGR2YUV_I420)


class VideoWriter:
    """Write BGR uint8 frames (H, W, 3) and, optionally, mono float32 audio to an MP4.

    Use as a context manager; :meth:`write` each frame in order. ``audio`` (n,) at
    :data:`AUDIO_SR` Hz is muxed progressively: after frame i, the samples up to time
    (i + 1) / fps. On an exception the partial file is removed.
    """

    def __init__(
        self,
        out: str | Path,
        width: int,
        height: int,
        fps: float,
        audio: np.ndarray | None = None,
        codec: str | None = None,
    ) -> None:
        import av

        if width % 2 or height % 2 or width < 16 or height < 16:
            raise InputError(f"video size must be even and at least 16 px, not {width}x{height}")
        self.out = Path(out)
        if not self.out.parent.is_dir():
            raise InputError("the output folder does not exist", self.out.parent)
        self.tmp = self.out.with_name(f".{self.out.stem}.tmp-{os.getpid()}{self.out.suffix}")
        self.rate = frame_rate(fps)
        self.codec = codec or video_codec()
        self.container = av.open(str(self.tmp), "w", format="mp4")
        self.video = self.container.add_stream(self.codec, rate=self.rate)
        self.video.width, self.video.height, self.video.pix_fmt = width, height, "yuv420p"
        self.video.time_base = 1 / self.rate
        if self.codec == "libx264":
            self.video.options = {"preset": PRESET, "crf": "20"}
        else:
            self.video.bit_rate = 2_000_000
        self.audio = None if audio is None else np.ascontiguousarray(audio, dtype=np.float32)
        self.sound = None
        if self.audio is not None:
            self.sound = self.container.add_stream("aac", rate=AUDIO_SR, layout="mono")
            self.sound.bit_rate = 128_000
        self._frames = 0
        self._audio_done = 0

    def __enter__(self) -> VideoWriter:
        return self

    def _push_audio(self, until: int) -> None:
        import av

        assert self.sound is not None and self.audio is not None
        until = min(until, self.audio.size)
        while self._audio_done + AUDIO_BLOCK <= until or (
            until == self.audio.size and self._audio_done < until
        ):
            stop = min(self._audio_done + AUDIO_BLOCK, until)
            chunk = self.audio[None, self._audio_done : stop]
            frame = av.AudioFrame.from_ndarray(chunk, format="fltp", layout="mono")
            frame.sample_rate = AUDIO_SR
            frame.pts = self._audio_done
            for packet in self.sound.encode(frame):
                self.container.mux(packet)
            self._audio_done = stop

    def write(self, image: np.ndarray) -> None:
        """Encode one BGR frame (H, W, 3) uint8 at the next frame time."""
        self.write_i420(bgr_to_i420(image))

    def write_i420(self, planes: np.ndarray) -> None:
        """Encode one frame already in I420 (:func:`bgr_to_i420`) at the next frame time."""
        import av

        frame = av.VideoFrame.from_ndarray(planes, format="yuv420p")
        frame.pts = self._frames
        for packet in self.video.encode(frame):
            self.container.mux(packet)
        self._frames += 1
        if self.sound is not None:
            self._push_audio(int(round(self._frames / self.rate * AUDIO_SR)))

    def close(self) -> None:
        """Flush the encoders, finish the file and move it to ``out``."""
        for packet in self.video.encode(None):
            self.container.mux(packet)
        if self.sound is not None and self.audio is not None:
            self._push_audio(self.audio.size)
            for packet in self.sound.encode(None):
                self.container.mux(packet)
        self.container.close()
        os.replace(self.tmp, self.out)

    def __exit__(self, exc_type, exc, tb) -> None:  # noqa: ANN001
        if exc_type is None:
            self.close()
            return
        try:
            self.container.close()
        finally:
            self.tmp.unlink(missing_ok=True)
