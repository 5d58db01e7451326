"""Bailando's music beats: the pure function against librosa called directly with Bailando's
parameters (extractor.py: HPSS, median onset strength, beat_track defaults, 30720 Hz, hop 512)
on real music; the ``bailando_beats`` family in a real store; evaluate --beat-source bailando
scoring against it."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from dancedata.compute.bailando_beats import BAILANDO_SR, bailando_beats
from dancedata.metrics.beats import bas_mint, beat_frames
from tests.helpers import run_cli
from tests.study.test_evaluate import SPLIT, fact_rows, model_path, noisy_motion, store  # noqa: F401


def librosa_bailando(y: np.ndarray, sr: int) -> np.ndarray:
    """Bailando's get_hpss → get_onset_strength → get_onset_beat, written from its code."""
    import librosa

    _, percussive = librosa.effects.hpss(y)
    onset_env = librosa.onset.onset_strength(y=percussive, aggregate=np.median, sr=sr)
    _, onset_beats = librosa.beat.beat_track(onset_envelope=onset_env, sr=sr)
    beats_one_hot = np.zeros(len(onset_env))
    for idx in onset_beats:
        beats_one_hot[idx] = 1
    return beats_one_hot


@pytest.mark.slow
@pytest.mark.real_data
def test_bailando_beats_equal_librosa_with_bailandos_parameters(real_data: Path) -> None:
    from dancedata.compute.audio_features import AudioFeatureConfig, beats, onset_envelope
    from dancedata.io.audio import load_mono

    path = real_data / "audio" / "Kevin_MacLeod_-_Vibe_Ace.hq.ogg"
    y = load_mono(path, BAILANDO_SR, max_seconds=40.0)
    ours = bailando_beats(y, BAILANDO_SR)
    reference = librosa_bailando(y, BAILANDO_SR)
    assert ours.dtype == np.uint8 and ours.shape == reference.shape
    np.testing.assert_array_equal(ours, reference.astype(np.uint8))
    assert ours.sum() > 40  # a beat every half second or so over 40 s
    fact = beats(onset_envelope(y, AudioFeatureConfig()), None, AudioFeatureConfig())
    assert not np.array_equal(fact[: len(ours)], ours)  # a different recipe, other beats


def test_bailando_beats_of_a_click_track() -> None:
    """Broadband noise bursts every 0.5 s (120 BPM; a median over mel bands needs energy in
    most bands): beats land on the bursts (± 1.5 frames at 60 fps)."""
    sr = BAILANDO_SR
    rng = np.random.default_rng(0)
    y = np.zeros(sr * 12, dtype=np.float32)
    clicks = np.arange(sr // 4, len(y) - sr, sr // 2)
    burst = (rng.normal(size=1500) * np.exp(-np.arange(1500) / 300)).astype(np.float32)
    for c in clicks:
        y[c : c + 1500] = burst
    frames = np.flatnonzero(bailando_beats(y, sr))
    click_frames = clicks / 512
    assert len(frames) >= 15
    assert np.max(np.min(np.abs(frames[:, None] - click_frames[None, :]), axis=1)) <= 1.5


@pytest.mark.slow
def test_featurize_family_and_evaluate_beat_source(
    store: Path,  # noqa: F811
    model_path: Path,  # noqa: F811
    tmp_path: Path,
) -> None:
    import dancedata
    from dancedata.compute.smpl_joints import smpl_joint_positions
    from dancedata.io.audio import load_mono
    from dancedata.io.smpl_model import load_smpl_model

    run_cli("featurize", str(store), "--audio-families", "bailando_beats", "-q")
    s = dancedata.open_store(store)
    assert "audio/beats_bailando" in s.array_names()
    attrs = dict(s.zarr("audio/beats_bailando").attrs)
    assert attrs["sr"] == BAILANDO_SR and "median" in attrs["recipe"]
    track = s.music.to_pylist()[0]
    y = load_mono(next((store.parent / "raw").rglob(f"{track['music_id']}.*")), BAILANDO_SR)
    stored = s.whole_array("audio/beats_bailando")[track["frame_start"] : track["frame_stop"]]
    np.testing.assert_array_equal(stored, bailando_beats(y, BAILANDO_SR)[: len(stored)])

    motion = noisy_motion(store, seed=9)
    gen = tmp_path / "gen"
    gen.mkdir()
    for seq, (aa, trans) in motion.items():
        np.save(gen / f"{seq}.npy", fact_rows(aa, trans))
    out = tmp_path / "res"
    run_cli("evaluate", str(store), "--generated", str(gen), *SPLIT, "--smpl-model",
            str(model_path), "--beat-source", "bailando", "--out", str(out))  # fmt: skip
    record = json.loads((out / "results.json").read_text())
    row = next(r for r in record["results"] if r["metric"] == "bas_mint")
    assert row["convention"]["music_beats"].startswith("audio/beats_bailando")
    model = load_smpl_model(model_path)
    direct = [
        bas_mint(smpl_joint_positions(model, *motion[q]), beat_frames(s.audio(q, "beats_bailando")))
        for q in s.seq_ids(split="train")
    ]
    assert row["value"] == pytest.approx(float(np.mean(direct)), abs=1e-9)
