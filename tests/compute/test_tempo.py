"""Tempo on demand (issue 23 item 5): :mod:`dancedata.compute.tempo`, ``dancedata tempo`` and the
tempo line ingest prints.

References are librosa's own functions called directly on the same signal and parameters:
``librosa.feature.tempogram`` / ``librosa.feature.tempo`` for the tempogram and the estimate,
``librosa.beat.beat_track`` for the tempo ingest recorded before (the time is in
bench/bench_tempo.py, not here). Inputs: click tracks written as real WAV files and the real
Vibe Ace track.
"""

from __future__ import annotations

import json

import librosa
import numpy as np
import pytest
import soundfile as sf

from dancedata.compute.tempo import (
    TEMPO_HOP,
    TEMPO_SR,
    estimate_tempo,
    lag_bpms,
    mean_tempogram,
    onset_envelope,
)
from dancedata.io.audio import load_mono
from tests.helpers import run_cli


def _clicks(
    bpm: float, seconds: float = 20.0, sr: int = TEMPO_SR, offbeats: float = 0.3
) -> np.ndarray:
    """A decaying 1 kHz click on every beat, and one ``offbeats`` as loud on each off-beat."""
    y = np.zeros(int(seconds * sr), np.float32)
    t = np.arange(int(0.03 * sr)) / sr
    click = (np.sin(2 * np.pi * 1000 * t) * np.exp(-t * 150)).astype(np.float32)
    for k, start in enumerate(np.arange(0.5, seconds - 0.1, 30.0 / bpm)):
        i = int(start * sr)
        y[i : i + click.size] += click * (1.0 if k % 2 == 0 else offbeats)
    return y


def _librosa_reference(y: np.ndarray) -> float:
    tempo, _ = librosa.beat.beat_track(y=y, sr=TEMPO_SR, hop_length=TEMPO_HOP)
    return float(np.atleast_1d(tempo)[0])


def test_mean_tempogram_equals_librosa_tempogram() -> None:
    rng = np.random.default_rng(0)
    for n, win in ((1000, 344), (500, 384), (50, 344)):
        env = np.abs(rng.normal(size=n))
        env[::7] += 3.0
        reference = librosa.feature.tempogram(
            onset_envelope=env, sr=TEMPO_SR, hop_length=TEMPO_HOP, win_length=win
        ).mean(axis=1)
        np.testing.assert_allclose(mean_tempogram(env, win), reference, rtol=0, atol=1e-12)


@pytest.mark.slow
@pytest.mark.parametrize("bpm", [92.0, 120.0, 135.0])
def test_estimate_equals_librosa_tempo_and_beat_track_on_clicks(bpm) -> None:
    y = _clicks(bpm)
    env = onset_envelope(y)
    np.testing.assert_array_equal(
        env, librosa.onset.onset_strength(y=y, sr=TEMPO_SR, hop_length=TEMPO_HOP,
                                          aggregate=np.median),
    )  # fmt: skip
    estimate = estimate_tempo(env)
    reference = librosa.feature.tempo(onset_envelope=env, sr=TEMPO_SR, hop_length=TEMPO_HOP)
    assert estimate.bpm == float(reference[0]) == _librosa_reference(y)
    bpms = lag_bpms(344, TEMPO_SR, TEMPO_HOP)
    step = abs(bpms[int(round(bpms[1] / bpm))] - bpms[int(round(bpms[1] / bpm)) + 1])
    assert abs(estimate.bpm - bpm) <= step  # within one lag of the true tempo
    assert estimate.half_bpm == estimate.bpm / 2 and estimate.double_bpm == estimate.bpm * 2
    shares = (estimate.confidence, estimate.half_confidence, estimate.double_confidence)
    assert abs(sum(shares) - 1.0) < 1e-12 and all(0 <= s <= 1 for s in shares)
    plain = estimate_tempo(onset_envelope(_clicks(bpm, offbeats=0.0)))
    assert plain.bpm == estimate.bpm  # the beats set the tempo, with or without off-beats
    assert plain.double_confidence < 0.1 < plain.confidence  # nothing at twice the rate
    assert estimate.double_confidence > plain.double_confidence  # off-beats are there


def test_silence_has_no_tempo() -> None:
    estimate = estimate_tempo(np.zeros(400))
    assert estimate.bpm == 0.0 and estimate.confidence == 0.0
    with pytest.raises(ValueError, match="1-d"):
        estimate_tempo(np.zeros((2, 3)))


@pytest.mark.real_data
def test_vibe_ace_estimate_equals_beat_track(real_data) -> None:
    y = load_mono(real_data / "audio" / "Kevin_MacLeod_-_Vibe_Ace.hq.ogg", TEMPO_SR)
    estimate = estimate_tempo(onset_envelope(y))
    assert estimate.bpm == _librosa_reference(y)
    assert round(estimate.bpm, 1) == 129.2


@pytest.mark.slow
@pytest.mark.real_data
def test_tempo_command_line_on_vibe_ace(real_data) -> None:
    """The line a user reads, by its exact text, on the real 61 s track."""
    path = real_data / "audio" / "Kevin_MacLeod_-_Vibe_Ace.hq.ogg"
    proc = run_cli("tempo", str(path))
    assert proc.stdout.splitlines() == [
        f"{path}: 129.2 BPM (confidence 0.29; half 64.6: 0.43, double 258.4: 0.28) over 61.5 s",
        "note: in 1 of 1 file(s) the half or double has the higher confidence: the estimate "
        "weighs the tempogram by a prior around 120 BPM (as librosa's beat_track and ingest do), "
        "the confidence does not; if you know the tempo, pass it to ingest with --bpm",
    ]
    assert proc.stderr == ""


@pytest.mark.slow
def test_tempo_command_text_json_and_errors(tmp_path) -> None:
    paths = []
    for bpm in (100.0, 128.0):
        path = tmp_path / f"clicks{bpm:.0f}.wav"
        sf.write(path, _clicks(bpm), TEMPO_SR)
        paths.append(path)
    text = run_cli("tempo", *map(str, paths)).stdout.strip().splitlines()
    estimates = [estimate_tempo(onset_envelope(load_mono(p, TEMPO_SR))) for p in paths]
    stronger = sum(e.stronger_alternative() is not None for e in estimates)
    assert len(text) == 2 + (stronger > 0)
    assert text[0].startswith(f"{paths[0]}: ") and "BPM (confidence" in text[0]
    if stronger:
        assert text[2].startswith(f"note: in {stronger} of 2 file(s) the half or double")
    rows = json.loads(run_cli("tempo", *map(str, paths), "--json").stdout)["tempo"]
    for path, row in zip(paths, rows, strict=True):
        expected = estimate_tempo(onset_envelope(load_mono(path, TEMPO_SR)))
        assert row["file"] == str(path) and row["bpm"] == expected.bpm
        assert row["confidence"] == expected.confidence and row["seconds"] == 20.0
        assert f"{expected.bpm:.1f} BPM" in text[paths.index(path)]
    bad = tmp_path / "noise.wav"
    bad.write_bytes(b"RIFF not really a wave file")
    proc = run_cli("tempo", str(bad), "--json", check=False)
    assert proc.returncode == 1
    error = json.loads(proc.stdout)
    assert error["exit_code"] == 1 and error["file"] == str(bad)


def test_ingest_prints_the_estimate_with_its_half_and_double(tmp_path, capsys) -> None:
    from dancedata.ingest.video.music import estimate_bpm

    y = _clicks(120.0)
    bpm = estimate_bpm(y, TEMPO_SR, tmp_path / "m.wav")
    assert bpm == _librosa_reference(y)
    line = capsys.readouterr().err.strip()
    expected = estimate_tempo(onset_envelope(y)).line()
    assert line == f"tempo of {tmp_path / 'm.wav'}: {expected}; --bpm B sets it"
    assert "half" in line and "double" in line


def test_stronger_alternative_names_the_candidate_above_the_estimate() -> None:
    """The note of `dancedata tempo` appears only when a neighbour out-scores the estimate."""
    from dancedata.compute.tempo import TempoEstimate

    plain = TempoEstimate(120.0, 0.5, 60.0, 0.2, 240.0, 0.3)
    assert plain.stronger_alternative() is None
    assert TempoEstimate(120.0, 0.29, 60.0, 0.43, 240.0, 0.28).stronger_alternative() == "half"
    assert TempoEstimate(120.0, 0.2, 60.0, 0.3, 240.0, 0.5).stronger_alternative() == "double"
