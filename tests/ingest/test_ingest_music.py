"""Music alone: ``ingest music`` makes a store of motion-less sequences, one per track, on which
featurize, segment, validate, plot and the measure windows work (audio-only items). Real audio
(decoded by the real decoders), synthetic clicks for the tempo estimate checked against librosa
called directly."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest
import soundfile as sf

import dancedata
from tests.helpers import run_cli


def _clicks(path, bpm: float = 120.0, seconds: float = 8.0, sr: int = 22050) -> None:
    """A click on every beat over faint noise, as a WAV file."""
    import librosa

    times = np.arange(0.25, seconds - 0.1, 60.0 / bpm)
    y = librosa.clicks(times=times, sr=sr, length=int(seconds * sr), click_duration=0.05)
    y += np.random.default_rng(0).normal(0, 0.01, y.shape)
    sf.write(path, (0.5 * y).astype(np.float32), sr)


@pytest.mark.slow
def test_synthetic_clicks_end_to_end(tmp_path):
    wav = tmp_path / "clicks.wav"
    _clicks(wav)
    store = tmp_path / "store"
    out = json.loads(
        run_cli(
            "ingest", "music", str(wav), "--store", str(store), "--genre", "gHO", "--json"
        ).stdout
    )
    assert out["counts"]["tracks"] == 1 and out["counts"]["bpm_estimated"] == 1
    ds = dancedata.open_store(store)
    (seq,) = ds.seq_ids()
    row = ds.sequence(seq)
    assert row["source"] == "music" and row["genre"] == "gHO" and row["bpm_estimated"]
    # the estimate is librosa's own on the recorded parameters
    import librosa

    y, sr = librosa.load(wav, sr=22050, mono=True)
    tempo, _ = librosa.beat.beat_track(y=y, sr=sr, hop_length=512)
    assert row["bpm"] == pytest.approx(float(np.atleast_1d(tempo)[0]))
    # n_frames = the feature frames featurize computes at 60 fps (sr 30720, hop 512)
    n_resampled = math.ceil(sf.info(wav).frames * 30720 / 22050)
    assert row["n_frames"] == 1 + n_resampled // 512
    assert ds.array_names() == []
    run_cli("featurize", str(store), "--stems", "none", "--quiet")
    run_cli("segment", str(store), "--quiet")
    run_cli("validate", str(store))
    ds = dancedata.open_store(store)
    assert ds.audio(seq, "onset_env").shape == (row["n_frames"],)
    windows = ds.measure_windows(motion=None)
    from dancedata.compute.measures import measure_bounds

    assert len(windows) == len(measure_bounds(row["n_frames"], row["bpm"], 60.0, 4)) > 0
    motion, audio = windows[0]
    assert motion is None and audio.shape[1] == 35


@pytest.mark.real_data
def test_real_tracks_with_given_tempo(real_data, tmp_path):
    audio = real_data / "audio"
    store = tmp_path / "store"
    run_cli("ingest", "music", str(audio), "--store", str(store), "--bpm", "120", "--quiet")
    ds = dancedata.open_store(store)
    assert sorted(ds.seq_ids()) == sorted(p.stem for p in audio.glob("*.ogg"))
    music = {r["music_id"]: r for r in ds.music.to_pylist()}
    for seq in ds.seq_ids():
        row = ds.sequence(seq)
        assert row["bpm"] == 120.0 and not row["bpm_estimated"]
        track = music[row["music_id"]]
        assert track["frame_stop"] - track["frame_start"] == row["n_frames"]
        assert track["n_samples"] == sf.info(audio / f"{seq}.ogg").frames
    run_cli("validate", str(store))


@pytest.mark.slow
def test_refusals(tmp_path):
    bad = run_cli("ingest", "music", str(tmp_path), "--store", str(tmp_path / "s"), check=False)
    assert bad.returncode == 1 and "no audio files given" in bad.stderr
    assert not (tmp_path / "s").exists()
    wav = tmp_path / "a.wav"
    _clicks(wav, seconds=1.0)
    bad = run_cli(
        "ingest", "music", str(wav), "--store", str(tmp_path / "s"), "--bpm", "0", check=False
    )
    assert bad.returncode == 1 and "--bpm must be between 20 and 400" in bad.stderr
    noise = tmp_path / "noise.wav"
    noise.write_bytes(b"RIFF not really")
    bad = run_cli("ingest", "music", str(noise), "--store", str(tmp_path / "s"), check=False)
    assert bad.returncode == 1 and "Traceback" not in bad.stderr and "noise.wav" in bad.stderr
