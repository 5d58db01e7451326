"""A video's clock (frame rate, frame count, duration) and, where possible, its audio track.

Pose estimators are run on video frames, so pose frame i belongs at time ``i / fps`` of the
video. This module reads that clock with OpenCV:

* ``CAP_PROP_FPS`` and ``CAP_PROP_FRAME_COUNT`` come from the container header. They can be
  missing (0, negative, NaN) or estimated from the duration; ``verify="auto"`` counts decoded
  frames only then, ``verify="always"`` counts every time and trusts the count (the property is
  kept for the record), ``verify="never"`` trusts the header.
* When the frame rate is missing it is estimated from decoded frame timestamps
  (``CAP_PROP_POS_MSEC``).

Audio: whether a track exists is read from the container itself (MP4/MOV ``hdlr`` boxes, AVI
``strh`` headers; other containers: unknown) with no external tool. Decoding it uses PyAV (the
optional ``viz`` extra, which ships its own FFmpeg libraries: no ``ffmpeg`` program on PATH is
needed; see :mod:`dancedata.io.av_audio`); without PyAV :func:`extract_audio` raises a clear
:class:`~dancedata.errors.InputError` naming the extra, and the alternative is ``--music FILE``.
"""

from __future__ import annotations

import math
import struct
from dataclasses import dataclass, field
from pathlib import Path
from typing import Literal

import numpy as np

from dancedata.errors import InputError

_MP4_CONTAINERS = {b"moov", b"trak", b"mdia"}


@dataclass(frozen=True)
class VideoClock:
    """The timing of one video file.

    Attributes:
        path: the video.
        fps: frames per second.
        n_frames: number of frames (decoded count when counted, else the header's).
        duration_s: ``n_frames / fps`` seconds (the span covered by the frames).
        width, height: frame size in pixels.
        frame_count_source: "property" (container header) or "decoded" (frames counted).
        fps_source: "property" or "timestamps".
        property_frame_count: the header's ``CAP_PROP_FRAME_COUNT`` as read (may be 0 or NaN).
        decoded_frame_count: frames actually decoded, or None when not counted.
        decoded_times: (decoded_frame_count,) presentation time of each decoded frame in
            seconds (``CAP_PROP_POS_MSEC``), or None when not counted.
    """

    path: Path
    fps: float
    n_frames: int
    duration_s: float
    width: int
    height: int
    frame_count_source: str
    fps_source: str
    property_frame_count: float
    decoded_frame_count: int | None
    decoded_times: np.ndarray | None = field(default=None, repr=False, compare=False)

    def frame_times(self) -> np.ndarray:
        """(n_frames,) nominal time of each frame in seconds: ``i / fps``."""
        return np.arange(self.n_frames, dtype=np.float64) / self.fps

    def decoded_frame_times(self) -> np.ndarray:
        """(n_frames,) decoded presentation times in seconds, for variable-frame-rate video.

        Raises:
            InputError: when the frames were not counted (read with ``verify="always"``) or
                the timestamps are not strictly increasing.
        """
        if self.decoded_times is None:
            raise InputError(
                "frame times were not decoded (read the clock with verify='always')", self.path
            )
        times = self.decoded_times
        if times.size > 1 and not (np.diff(times) > 0).all():
            raise InputError(
                "decoded frame timestamps are not strictly increasing; use the "
                "nominal frame times (i / fps)",
                self.path,
            )
        return times

    def to_dict(self) -> dict:
        """JSON-ready record for a manifest."""
        return {
            "path": str(self.path),
            "fps": self.fps,
            "n_frames": self.n_frames,
            "duration_s": self.duration_s,
            "width": self.width,
            "height": self.height,
            "frame_count_source": self.frame_count_source,
            "fps_source": self.fps_source,
            "property_frame_count": (
                self.property_frame_count if math.isfinite(self.property_frame_count) else None
            ),
            "decoded_frame_count": self.decoded_frame_count,
        }


def _open(path: Path):
    import cv2  # heavy import kept out of CLI start-up

    if not path.is_file():
        raise InputError("video file not found", path)
    cap = cv2.VideoCapture(str(path))
    if not cap.isOpened():
        cap.release()
        raise InputError(
            "cannot open as a video (not a video file, or a codec this OpenCV build lacks)", path
        )
    return cap


def count_frames(path: str | Path) -> tuple[int, np.ndarray]:
    """Decode-count the frames of a video: (count, (count,) timestamps in seconds).

    Timestamps are OpenCV's ``CAP_PROP_POS_MSEC`` of each frame (presentation time).
    """
    import cv2

    path = Path(path)
    cap = _open(path)
    stamps: list[float] = []
    try:
        while cap.grab():
            stamps.append(cap.get(cv2.CAP_PROP_POS_MSEC) / 1000.0)
    finally:
        cap.release()
    return len(stamps), np.asarray(stamps, dtype=np.float64)


def _valid_count(value: float) -> bool:
    return math.isfinite(value) and value > 0 and value == round(value)


def _fps_from_stamps(stamps: np.ndarray) -> float | None:
    if stamps.size < 2:
        return None
    steps = np.diff(stamps)
    steps = steps[steps > 0]
    if steps.size == 0:
        return None
    return float(1.0 / np.median(steps))


def read_video_clock(
    path: str | Path, verify: Literal["auto", "always", "never"] = "auto"
) -> VideoClock:
    """Read fps, frame count and duration of a video (module docstring: the ``verify`` rule).

    Raises:
        InputError: naming the file, when it is missing, cannot be opened, has no frames, or has
            no usable frame rate.
    """
    import cv2

    path = Path(path)
    if verify not in ("auto", "always", "never"):
        raise InputError(f"verify must be 'auto', 'always' or 'never', not {verify!r}", path)
    cap = _open(path)
    try:
        fps = float(cap.get(cv2.CAP_PROP_FPS))
        prop_count = float(cap.get(cv2.CAP_PROP_FRAME_COUNT))
        width = int(cap.get(cv2.CAP_PROP_FRAME_WIDTH))
        height = int(cap.get(cv2.CAP_PROP_FRAME_HEIGHT))
    finally:
        cap.release()
    fps_ok = math.isfinite(fps) and fps > 0
    count_ok = _valid_count(prop_count)
    decoded: int | None = None
    stamps = np.zeros(0)
    if verify == "always" or (verify == "auto" and not (fps_ok and count_ok)):
        decoded, stamps = count_frames(path)
    fps_source = "property"
    if not fps_ok:
        estimate = _fps_from_stamps(stamps)
        if estimate is None:
            raise InputError("the video has no frame rate and it cannot be estimated", path)
        fps, fps_source = estimate, "timestamps"
    if decoded is not None:
        n_frames, source = decoded, "decoded"
    elif count_ok:
        n_frames, source = int(prop_count), "property"
    else:
        raise InputError(
            f"the video header gives no frame count ({prop_count}) and verify='never'", path
        )
    if n_frames <= 0:
        raise InputError("the video has no decodable frames", path)
    return VideoClock(
        path=path,
        fps=fps,
        n_frames=n_frames,
        duration_s=n_frames / fps,
        width=width,
        height=height,
        frame_count_source=source,
        fps_source=fps_source,
        property_frame_count=prop_count,
        decoded_frame_count=decoded,
        decoded_times=stamps if decoded is not None else None,
    )


# ----------------------------------------------------------------------------- audio track


def _mp4_handlers(fh, start: int, end: int, out: list[str], depth: int = 0) -> None:
    """Collect ``hdlr`` handler types of tracks (moov/trak/mdia/hdlr) between two offsets."""
    pos = start
    while pos + 8 <= end:
        fh.seek(pos)
        head = fh.read(8)
        if len(head) < 8:
            return
        size, kind = struct.unpack(">I4s", head)
        header = 8
        if size == 1:
            size = struct.unpack(">Q", fh.read(8))[0]
            header = 16
        elif size == 0:
            size = end - pos
        if size < header:
            return  # corrupt box: stop rather than loop
        if kind in _MP4_CONTAINERS and depth < 4:
            _mp4_handlers(fh, pos + header, min(pos + size, end), out, depth + 1)
        elif kind == b"hdlr" and depth == 3:  # moov/trak/mdia/hdlr, not meta/hdlr
            fh.seek(pos + header + 8)  # version+flags, pre_defined
            out.append(fh.read(4).decode("latin-1"))
        pos += size


def _avi_stream_types(fh, end: int) -> list[str]:
    """fccType of each ``strh`` inside RIFF AVI ``LIST hdrl``/``LIST strl``."""
    out: list[str] = []

    def walk(pos: int, stop: int) -> None:
        while pos + 8 <= stop:
            fh.seek(pos)
            cid, size = struct.unpack("<4sI", fh.read(8))
            if cid == b"LIST":
                kind = fh.read(4)
                if kind in (b"hdrl", b"strl"):
                    walk(pos + 12, min(pos + 8 + size, stop))
                if kind == b"movi":
                    return
            elif cid == b"strh":
                out.append(fh.read(4).decode("latin-1"))
            pos += 8 + size + (size & 1)

    walk(12, end)
    return out


def audio_track_present(path: str | Path) -> bool | None:
    """True/False when the container says whether it holds an audio track; None if unknown.

    Reads MP4/MOV (``soun`` handler) and AVI (``auds`` stream) headers directly; other
    containers (MKV, WebM, ...) give None.
    """
    path = Path(path)
    if not path.is_file():
        raise InputError("video file not found", path)
    size = path.stat().st_size
    with path.open("rb") as fh:
        head = fh.read(12)
        if head[:4] == b"RIFF" and head[8:12] == b"AVI ":
            return "auds" in _avi_stream_types(fh, min(size, 8 + struct.unpack("<I", head[4:8])[0]))
        if head[4:8] in (b"ftyp", b"moov", b"mdat", b"free", b"wide", b"skip"):
            handlers: list[str] = []
            _mp4_handlers(fh, 0, size, handlers)
            return "soun" in handlers if handlers else None
    return None


def extract_audio(
    path: str | Path, sr: int | None = None, mono: bool = True
) -> tuple[np.ndarray, int]:
    """Decode a video's audio track: (samples float32 in [-1, 1], sample rate in Hz).

    Samples are (n,) when ``mono`` (channel mean) else (channels, n). ``sr`` resamples (librosa,
    soxr_hq). Decoded with PyAV (:func:`dancedata.io.av_audio.decode_audio_track`).

    Raises:
        InputError: naming the video, when it has no audio track, when PyAV (the ``viz`` extra)
            is not installed (install it, or give the music file with ``--music``), or when
            decoding fails.
    """
    from dancedata.io.av_audio import AV_HINT, av_available, decode_audio_track

    path = Path(path)
    if audio_track_present(path) is False:
        raise InputError("the video has no audio track; give the music with --music FILE", path)
    if not av_available():
        raise InputError(
            "reading audio from a video needs PyAV, from the optional 'viz' extra, which is not "
            f"installed: {AV_HINT}, or give the music with --music FILE",
            path,
        )
    pcm, native_sr = decode_audio_track(path)
    samples = pcm.mean(axis=0) if mono else pcm
    if sr is not None and sr != native_sr:
        import librosa

        samples = librosa.resample(samples, orig_sr=native_sr, target_sr=sr).astype(np.float32)
        native_sr = sr
    return np.ascontiguousarray(samples, dtype=np.float32), native_sr
