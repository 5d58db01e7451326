"""Hostile audio: long tracks decode only the span their motions need (bounded memory) under a
documented limit; NaN, Inf and 1e30 samples get one line naming the file and the real problem;
a file whose extension lies is decoded by its content. Every file is written by soundfile and
read back by the real decoder (libsndfile through soundfile)."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import librosa
import numpy as np
import pytest
import soundfile as sf

from dancedata.compute.audio_features import AudioFeatureConfig
from dancedata.errors import InputError
from dancedata.featurize.families.audio_base import AudioSettings
from dancedata.featurize.featurize import FeaturizeOptions, featurize
from dancedata.featurize.music_inputs import DECODE_MARGIN_S, decode_span_s
from dancedata.ingest.bvh import BvhIngestOptions, ingest_bvh
from dancedata.io.audio import load_mono
from dancedata.io.audio_decode import MAX_ABS_SAMPLE, decode_mono
from dancedata.store.reader import _VersionReader
from tests.helpers import REPO, run_cli
from tests.ingest.test_ingest_bvh import synthetic_bvh

FPS = 30.0
FACT_ONLY = AudioSettings(stems="none")


def silent_flac(path: Path, seconds: float, sr: int = 44100, fmt: str = "FLAC") -> Path:
    """Digital silence written minute by minute (FLAC packs it to a few hundred bytes per
    second, so an hour is ~0.5 MB on disk and 635 MB of float32 once decoded at 44.1 kHz)."""
    block = np.zeros(sr * 60, np.int16)
    left = int(round(seconds * sr))
    with sf.SoundFile(path, "w", sr, 1, format=fmt, subtype="PCM_16") as handle:
        while left > 0:
            k = min(left, block.size)
            handle.write(block[:k])
            left -= k
    return path


def clicks(path: Path, seconds: float, sr: int = 22050, subtype: str = "PCM_16") -> np.ndarray:
    """Noise with a click every half second: onsets and a tempo for the features."""
    rng = np.random.default_rng(3)
    y = 0.05 * rng.standard_normal(int(seconds * sr))
    for k in range(0, y.size, sr // 2):
        y[k : k + 200] += 0.8
    y = y.astype(np.float32)
    sf.write(path, y, sr, subtype=subtype)
    return y


def dance(path: Path, seconds: float) -> Path:
    t = np.arange(int(seconds * FPS))[:, None] / FPS
    return synthetic_bvh(path, FPS, 20 * np.sin(t * [1.0, 2.0, 3.0]))


def store_with(tmp_path: Path, music: Path, dance_s: float = 10.0) -> Path:
    store = tmp_path / "store"
    bvh = dance(tmp_path / "dance.bvh", dance_s)
    ingest_bvh(store, [bvh], BvhIngestOptions(music=music, bpm=120.0, fps=FPS))
    return store


def one_line(proc: subprocess.CompletedProcess) -> str:
    assert proc.returncode == 1, proc.stdout + proc.stderr
    lines = [line for line in proc.stderr.splitlines() if line.strip()]
    assert len(lines) == 1 and "Traceback" not in proc.stderr, proc.stderr
    return lines[0]


# ----------------------------------------------------------------------------- decoded span


def test_decode_span_follows_its_formula() -> None:
    cfg = AudioFeatureConfig(fps=60.0)
    # frame N-1 is centred on sample (N-1)*512 and reaches n_fft/2 past it, plus the margin
    span, partial = decode_span_s(600, cfg, 36000.0)
    assert partial and span == pytest.approx((599 * 512 + 1025) / 30720 + DECODE_MARGIN_S)
    assert decode_span_s(600, cfg, 20.0) == (20.0, False)  # shorter track: whole
    assert decode_span_s(None, cfg, 500.0) == (500.0, False)  # no sequence: whole


@pytest.mark.slow
def test_decode_reads_only_the_first_seconds_of_a_long_flac(tmp_path: Path) -> None:
    path = silent_flac(tmp_path / "hour.flac", 3600.0)
    assert path.stat().st_size < 2_000_000
    decoded = decode_mono(path, 30720, max_seconds=40.0)
    assert decoded.native_samples == 40 * 44100 and decoded.header_samples == 3600 * 44100
    assert not decoded.whole and decoded.y.size == 40 * 30720
    assert decoded.decoded_s == pytest.approx(40.0)


@pytest.mark.slow
def test_ten_minute_flac_under_a_ten_second_dance_decodes_forty_seconds(tmp_path: Path) -> None:
    store = store_with(tmp_path, silent_flac(tmp_path / "long.flac", 600.0))
    result = featurize(store, FeaturizeOptions(audio_settings=FACT_ONLY, use_cache=False))
    reader = _VersionReader(store, result.version)
    music = reader.table("music").to_pylist()[0]
    expected, partial = decode_span_s(300, AudioFeatureConfig(fps=FPS), 600.0)
    assert partial and music["decoded_s"] == pytest.approx(expected)
    frames = music["frame_stop"] - music["frame_start"]
    assert frames == 1 + int(np.ceil(expected * 44100) * FPS * 512 / 44100) // 512
    assert music["duration_s"] == 600.0  # the file is still described whole
    seq = reader.table("sequences").to_pylist()[0]
    assert seq["audio_frames"] == seq["n_frames"] == 300
    assert seq["audio_truncated_frames"] == frames - 300


@pytest.mark.slow
def test_features_on_the_span_match_librosa_on_the_whole_track(tmp_path: Path) -> None:
    """Onset envelope and MFCC are local: on the frames the dance uses they equal librosa's on
    the whole three-minute file (the span ends 30 s after them)."""
    path = tmp_path / "clicks.flac"
    clicks(path, 180.0)
    store = store_with(tmp_path, path)
    result = featurize(store, FeaturizeOptions(audio_settings=FACT_ONLY, use_cache=False))
    reader = _VersionReader(store, result.version)
    assert reader.table("music").to_pylist()[0]["decoded_s"] < 60
    sr = int(FPS * 512)
    y, _ = librosa.load(path, sr=sr)
    env = librosa.onset.onset_strength(y=y, sr=sr, hop_length=512)
    mfcc = librosa.feature.mfcc(y=y, sr=sr, n_mfcc=20, hop_length=512).T
    got_env = np.asarray(reader.array("audio/onset_env")[:300])
    got_mfcc = np.asarray(reader.array("audio/mfcc")[:300])
    np.testing.assert_allclose(got_env, env[:300], rtol=1e-5, atol=1e-5)
    np.testing.assert_allclose(got_mfcc, mfcc[:300], rtol=1e-4, atol=1e-3)


@pytest.mark.slow
def test_long_span_is_refused_before_decoding_unless_allowed(tmp_path: Path) -> None:
    store = store_with(tmp_path, silent_flac(tmp_path / "long.flac", 120.0), dance_s=20.0)
    with pytest.raises(InputError, match=r"would decode 50 s of audio .*over the 30 s limit"):
        featurize(store, FeaturizeOptions(audio_settings=FACT_ONLY, max_audio_seconds=30))
    proc = run_cli(
        "featurize", str(store), "--stems", "none", "--max-audio-seconds", "30", "-q", check=False
    )
    line = one_line(proc)
    assert str(tmp_path / "long.flac") in line and "--max-audio-seconds 51" in line
    assert [p.name for p in (store / "versions").iterdir()] == ["v1"]  # nothing written
    run_cli("featurize", str(store), "--stems", "none", "--max-audio-seconds", "0", "-q")
    assert _VersionReader(store).version == "v2"


@pytest.mark.slow
def test_peak_memory_of_an_hour_of_flac_is_that_of_the_span(tmp_path: Path) -> None:
    """Peak RSS of featurize in a subprocess that reports its own VmHWM (not ru_maxrss, which
    survives exec and would include pytest's own peak): decoding the whole
    hour at 44.1 kHz alone takes 0.64 GB (FACT alone peaked at 3.8 GB before the span was
    bounded); the 40 s span keeps it near the interpreter's own ~0.5 GB."""
    store = store_with(tmp_path, silent_flac(tmp_path / "hour.flac", 3600.0))
    code = (
        "import resource, sys\n"
        "from dancedata.cli.main import main\n"
        "sys.argv = ['dancedata', 'featurize', sys.argv[1], '--stems', 'none', '-q',"
        " '--no-cache']\n"
        "try:\n    main()\nexcept SystemExit as exc:\n    assert not exc.code, exc.code\n"
        "print(int(open('/proc/self/status').read().split('VmHWM:')[1].split()[0]))\n"
    )
    proc = subprocess.run(
        [sys.executable, "-c", code, str(store)],
        cwd=REPO,
        capture_output=True,
        text=True,
        timeout=600,
        check=True,
    )
    peak_kb = int(proc.stdout.split()[-1])
    assert peak_kb < 900_000, f"featurize peaked at {peak_kb / 1e6:.2f} GB"
    assert _VersionReader(store).table("music").to_pylist()[0]["decoded_s"] < 45


# ----------------------------------------------------------------------------- bad samples


@pytest.mark.parametrize(
    ("value", "expect"),
    [
        (np.nan, r"non-finite audio sample \(nan\) at sample 1000 \(0\.045 s\), channel 1"),
        (np.inf, r"non-finite audio sample \(inf\) at sample 1000"),
        (-np.inf, r"non-finite audio sample \(-inf\)"),
        (1e30, r"out-of-range audio sample \(1e\+30\) at sample 1000 .*within ±1000"),
    ],
)
def test_bad_samples_are_named_not_called_unreadable(
    tmp_path: Path, value: float, expect: str
) -> None:
    y = np.full((22050, 2), 0.1, np.float32)
    y[1000, 1] = value
    path = tmp_path / "bad.wav"
    sf.write(path, y, 22050, subtype="FLOAT")
    with pytest.raises(InputError, match=expect) as info:
        load_mono(path, 30720)
    assert info.value.path == str(path) and "truncated" not in str(info.value)


def test_float_samples_a_little_past_full_scale_are_audio(tmp_path: Path) -> None:
    y = np.full(22050, 0.5, np.float32)
    y[10] = 1.5
    y[11] = -MAX_ABS_SAMPLE
    path = tmp_path / "clipped.wav"
    sf.write(path, y, 22050, subtype="FLOAT")
    np.testing.assert_array_equal(load_mono(path, 30720), librosa.load(path, sr=30720)[0])


@pytest.mark.slow
def test_featurize_names_the_file_with_a_nan_sample(tmp_path: Path) -> None:
    path = tmp_path / "nan.wav"
    y = clicks(path, 15.0, subtype="FLOAT")
    y[44100] = np.nan  # at 2.000 s
    sf.write(path, y, 22050, subtype="FLOAT")
    store = store_with(tmp_path, path)
    line = one_line(run_cli("featurize", str(store), "--stems", "none", "-q", check=False))
    assert line.startswith(f"error: {path}: non-finite audio sample (nan) at sample 44100 (2.000")
    assert [p.name for p in (store / "versions").iterdir()] == ["v1"]


# ----------------------------------------------------------------------------- lying extension


def test_flac_named_wav_is_decoded_by_its_content(tmp_path: Path) -> None:
    flac = tmp_path / "song.flac"
    clicks(flac, 5.0)
    liar = tmp_path / "song.wav"
    liar.write_bytes(flac.read_bytes())
    assert liar.read_bytes()[:4] == b"fLaC"
    np.testing.assert_array_equal(load_mono(liar, 30720), librosa.load(flac, sr=30720)[0])


@pytest.mark.slow
def test_twenty_minute_silent_flac_named_wav_through_featurize(tmp_path: Path) -> None:
    liar = silent_flac(tmp_path / "quiet.wav", 1200.0)
    store = store_with(tmp_path, liar)
    result = featurize(store, FeaturizeOptions(audio_settings=FACT_ONLY, use_cache=False))
    music = _VersionReader(store, result.version).table("music").to_pylist()[0]
    assert music["duration_s"] == 1200.0 and music["decoded_s"] < 45


def test_content_no_decoder_reads_is_refused_naming_the_extension_lie(tmp_path: Path) -> None:
    path = tmp_path / "notes.wav"
    path.write_bytes(b"these are my notes, not audio\n" * 100)
    with pytest.raises(InputError, match=r"cannot decode audio: .*whatever the extension"):
        decode_mono(path, 30720)


def test_tempo_of_a_track_past_the_limit_is_not_estimated_by_decoding_it_all(
    tmp_path: Path,
) -> None:
    from dancedata.io.audio_decode import DEFAULT_MAX_AUDIO_SECONDS

    music = silent_flac(tmp_path / "long.flac", DEFAULT_MAX_AUDIO_SECONDS + 60)
    bvh = dance(tmp_path / "dance.bvh", 3.0)
    with pytest.raises(InputError, match=r"estimating its tempo would decode all .*--bpm") as info:
        ingest_bvh(tmp_path / "store", [bvh], BvhIngestOptions(music=music, fps=FPS))
    assert info.value.path == str(music)
