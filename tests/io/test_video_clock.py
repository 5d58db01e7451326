"""Video clock (fps, frame count, duration) and audio-track detection/extraction."""

from __future__ import annotations

import struct
import sys
from pathlib import Path

import cv2
import numpy as np
import pytest

from dancedata.errors import InputError
from dancedata.io.video_clock import (
    audio_track_present,
    count_frames,
    extract_audio,
    read_video_clock,
)
from tests.helpers import importorskip_unless_ci

RAGA = Path("openpose")


def write_video(path: Path, fps: float, n_frames: int, codec: str, size=(96, 64)) -> Path:
    """Write ``n_frames`` frames with the frame number drawn on each; returns ``path``."""
    writer = cv2.VideoWriter(str(path), cv2.VideoWriter_fourcc(*codec), fps, size)
    assert writer.isOpened(), f"this OpenCV cannot write {codec} to {path.suffix}"
    for i in range(n_frames):
        image = np.zeros((size[1], size[0], 3), np.uint8)
        cv2.putText(image, str(i), (4, 40), cv2.FONT_HERSHEY_SIMPLEX, 1.0, (255, 255, 255), 2)
        writer.write(image)
    writer.release()
    return path


# ----------------------------------------------------------------------------- real data


@pytest.mark.real_data
@pytest.mark.parametrize(
    "name, n_frames, size",
    [("raga_example_1person", 125, (1920, 1080)), ("raga_example_3people", 250, (768, 576))],
)
def test_raga_video_clock(real_data: Path, name: str, n_frames: int, size) -> None:
    path = real_data / RAGA / name / "short_video.mp4"
    clock = read_video_clock(path)
    assert clock.fps == 25.0
    assert clock.n_frames == n_frames and clock.frame_count_source == "property"
    assert clock.duration_s == pytest.approx(n_frames / 25.0, abs=1e-12)
    assert (clock.width, clock.height) == size
    assert clock.to_dict()["decoded_frame_count"] is None


@pytest.mark.real_data
def test_raga_3people_decoded_count_agrees_with_header(real_data: Path) -> None:
    clock = read_video_clock(
        real_data / RAGA / "raga_example_3people" / "short_video.mp4", verify="always"
    )
    assert clock.decoded_frame_count == 250 == clock.property_frame_count
    assert clock.frame_count_source == "decoded"
    assert clock.duration_s == pytest.approx(10.0)


@pytest.mark.real_data
def test_raga_audio_tracks(real_data: Path) -> None:
    # The 3-people clip carries an 'soun' track (an "Apple Sound Media Handler"); the 1-person
    # clip has only video. Read from the MP4 boxes, no ffmpeg needed.
    assert audio_track_present(real_data / RAGA / "raga_example_3people" / "short_video.mp4")
    assert not audio_track_present(real_data / RAGA / "raga_example_1person" / "short_video.mp4")


# ----------------------------------------------------------------------------- generated videos


@pytest.mark.parametrize(
    "codec, suffix, fps, n_frames",
    [
        ("mp4v", ".mp4", 25.0, 40),
        ("MJPG", ".avi", 30.0, 37),
        ("mp4v", ".mov", 24.0, 29),
        ("MJPG", ".avi", 29.97, 31),
        ("mp4v", ".mp4", 50.0, 61),
    ],
)
@pytest.mark.parametrize("verify", ["auto", "always", "never"])
def test_generated_video_read_back_exactly(
    tmp_path: Path, codec: str, suffix: str, fps: float, n_frames: int, verify: str
) -> None:
    path = write_video(tmp_path / f"clip{suffix}", fps, n_frames, codec)
    clock = read_video_clock(path, verify=verify)
    assert clock.fps == pytest.approx(fps, rel=1e-9)
    assert clock.n_frames == n_frames
    assert clock.duration_s == pytest.approx(n_frames / fps, rel=1e-9)
    assert (clock.width, clock.height) == (96, 64)
    assert clock.frame_count_source == ("decoded" if verify == "always" else "property")
    assert audio_track_present(path) is False


def _zero_avi_frame_count(path: Path) -> None:
    """Blank the AVI header's frame counts (avih dwTotalFrames, strh dwLength), as some
    streaming writers leave them."""
    data = bytearray(path.read_bytes())
    avih, strh = data.find(b"avih"), data.find(b"strh")
    assert struct.unpack("<I", data[avih + 24 : avih + 28])[0] > 0
    data[avih + 24 : avih + 28] = struct.pack("<I", 0)  # 8-byte chunk header + 4th field
    data[strh + 40 : strh + 44] = struct.pack("<I", 0)  # 8 + fcc type/handler + 6 fields
    path.write_bytes(bytes(data))


def test_missing_frame_count_is_counted_by_decoding(tmp_path: Path) -> None:
    path = write_video(tmp_path / "clip.avi", 30.0, 37, "MJPG")
    _zero_avi_frame_count(path)
    clock = read_video_clock(path)  # verify="auto"
    assert clock.property_frame_count == 0
    assert clock.frame_count_source == "decoded" and clock.n_frames == 37
    assert clock.duration_s == pytest.approx(37 / 30)
    with pytest.raises(InputError, match="no frame count .* verify='never'"):
        read_video_clock(path, verify="never")


def test_decoded_timestamps_are_frame_index_over_fps(tmp_path: Path) -> None:
    path = write_video(tmp_path / "clip.mp4", 25.0, 30, "mp4v")
    count, stamps = count_frames(path)
    assert count == 30
    np.testing.assert_allclose(stamps, np.arange(30) / 25.0, atol=1e-6)
    np.testing.assert_allclose(read_video_clock(path).frame_times(), np.arange(30) / 25.0)


def test_unreadable_videos(tmp_path: Path) -> None:
    with pytest.raises(InputError, match="video file not found"):
        read_video_clock(tmp_path / "absent.mp4")
    fake = tmp_path / "fake.mp4"
    fake.write_text("this is not a video")
    with pytest.raises(InputError, match="cannot open as a video") as info:
        read_video_clock(fake)
    assert str(info.value).startswith(str(fake))


# ----------------------------------------------------------------------------- container parsing


def _box(kind: bytes, payload: bytes = b"") -> bytes:
    return struct.pack(">I4s", 8 + len(payload), kind) + payload


def _hdlr(handler: bytes) -> bytes:
    return _box(b"hdlr", b"\0" * 8 + handler + b"\0" * 12 + b"handler\0")


def _mp4(*handlers: bytes, meta_handler: bytes = b"mdir") -> bytes:
    tracks = b"".join(_box(b"trak", _box(b"mdia", _hdlr(h))) for h in handlers)
    udta = _box(b"udta", _box(b"meta", b"\0" * 4 + _hdlr(meta_handler)))
    big_mdat = struct.pack(">I4sQ", 1, b"mdat", 16 + 10) + b"\0" * 10  # 64-bit box size
    return _box(b"ftyp", b"isom\0\0\0\0") + big_mdat + _box(b"moov", tracks + udta)


def _chunk(cid: bytes, data: bytes) -> bytes:
    return cid + struct.pack("<I", len(data)) + data + (b"\0" if len(data) % 2 else b"")


def _avi(*stream_types: bytes) -> bytes:
    strls = b"".join(
        _chunk(b"LIST", b"strl" + _chunk(b"strh", t + b"\0" * 52)) for t in stream_types
    )
    body = b"AVI " + _chunk(b"LIST", b"hdrl" + _chunk(b"avih", b"\0" * 56) + strls)
    body += _chunk(b"LIST", b"movi")
    return b"RIFF" + struct.pack("<I", len(body)) + body


@pytest.mark.parametrize(
    "data, expected",
    [
        (_mp4(b"vide", b"soun"), True),
        (_mp4(b"vide"), False),
        (_mp4(b"vide", meta_handler=b"soun"), False),  # a metadata handler is not a track
        (_avi(b"vids", b"auds"), True),
        (_avi(b"vids"), False),
        (b"\x1aE\xdf\xa3" + b"\0" * 40, None),  # Matroska: not inspected
    ],
)
def test_audio_track_from_container_headers(tmp_path: Path, data: bytes, expected) -> None:
    path = tmp_path / "clip.bin"
    path.write_bytes(data)
    assert audio_track_present(path) is expected


# ----------------------------------------------------------------------------- audio extraction


def test_video_without_audio_track_says_use_music(tmp_path: Path) -> None:
    path = write_video(tmp_path / "clip.mp4", 25.0, 5, "mp4v")
    with pytest.raises(InputError, match="no audio track; give the music with --music"):
        extract_audio(path)


@pytest.mark.real_data
def test_missing_pyav_is_reported(real_data: Path, monkeypatch) -> None:
    monkeypatch.setitem(sys.modules, "av", None)  # `import av` raises ImportError
    path = real_data / RAGA / "raga_example_3people" / "short_video.mp4"
    with pytest.raises(InputError, match=r"needs PyAV.*dancedata\[viz\].*--music") as info:
        extract_audio(path)
    assert str(info.value).startswith(str(path))


@pytest.mark.real_data
def test_extract_audio_with_pyav(real_data: Path) -> None:
    importorskip_unless_ci("av")
    path = real_data / RAGA / "raga_example_3people" / "short_video.mp4"
    samples, sr = extract_audio(path, sr=22050)
    assert sr == 22050 and samples.ndim == 1
    assert samples.size / sr == pytest.approx(10.0, abs=0.1)
    assert np.abs(samples).max() > 0.01
    stereo, native = extract_audio(path, mono=False)
    assert native == 48000 and stereo.shape[0] == 2
    assert stereo.shape[1] / native == pytest.approx(10.0, abs=0.1)


def test_pyav_decodes_the_samples_written(tmp_path: Path) -> None:
    """A lossless (PCM) track written with PyAV is read back sample for sample; an AAC track
    keeps the tone (lossy: compared by correlation after the codec's delay is trimmed)."""
    importorskip_unless_ci("av")
    from tests.av_media import tone, write_video_with_audio

    audio = tone(1.5, 44100)
    exact = np.clip(np.round(audio * 32768.0), -32768, 32767) / 32768.0
    mov = write_video_with_audio(tmp_path / "clip.mov", 25.0, 30, audio, 44100, "pcm_s16le")
    assert audio_track_present(mov) is True
    samples, sr = extract_audio(mov, mono=False)
    assert sr == 44100 and samples.shape == audio.shape
    np.testing.assert_array_equal(samples, exact.astype(np.float32))
    mono, _ = extract_audio(mov)
    np.testing.assert_allclose(mono, exact.mean(axis=0), atol=1e-7)

    clean = tone(1.5, 44100)
    mp4 = write_video_with_audio(tmp_path / "clip.mp4", 25.0, 30, clean, 44100, "aac")
    lossy, sr = extract_audio(mp4, mono=False)
    assert sr == 44100 and lossy.shape[0] == 2
    assert abs(lossy.shape[1] - clean.shape[1]) <= 2048  # AAC frames of 1024 samples
    n = min(lossy.shape[1], clean.shape[1])
    for ch in range(2):
        corr = np.corrcoef(lossy[ch, 2048 : n - 2048], clean[ch, 2048 : n - 2048])[0, 1]
        assert corr > 0.98
