"""segment --phase auto (issue 14, item 2) and the exact measure times (item 6, bullet 3).

The synthetic music (dancedata.synth.music) starts on a downbeat at t = 0 and keeps a constant
tempo, so its downbeats are known: frame 0 of every synthetic AIST++ sequence, and
``(-cut) mod frames_per_measure`` for a track whose first ``cut`` feature frames are removed.
"""

from __future__ import annotations

import json
import math
import shutil

import numpy as np
import pyarrow.parquet as pq
import pytest

from dancedata.compute.audio_features import AudioFeatureConfig, fact_features
from dancedata.compute.downbeat import estimate_downbeat, sequence_phase, wrap_phase
from dancedata.compute.measures import measure_bounds, measure_grid
from dancedata.io.aist_names import GENRES, music_bpm
from dancedata.synth.catalog import stable_seed
from dancedata.synth.music import synth_dance_music
from tests.helpers import run_cli

FPS = 60.0
CFG = AudioFeatureConfig(fps=FPS)


def _cyclic_error(estimate: float, truth: float, fpm: float) -> float:
    return (estimate - truth + fpm / 2) % fpm - fpm / 2


AIST_MUSIC_IDS = [f"m{genre[1:]}{k}" for genre in GENRES for k in range(6)]


@pytest.mark.slow
@pytest.mark.parametrize("music_id", AIST_MUSIC_IDS)
def test_estimate_finds_the_known_downbeat_of_every_synthetic_track(music_id):
    """Every song of the synthetic twin (its tempo and seed, as `synth aist` writes it), cut to
    start `cut` frames into a measure: its first downbeat is then at frame (-cut) mod fpm. The
    estimate, from the real FACT features, is within a frame of it (measured: 0.32 at worst)."""
    bpm = music_bpm(music_id)
    cut = stable_seed(music_id, "cut") % 97
    y = synth_dance_music(bpm, 12.0, sr=CFG.sr, seed=stable_seed(0, music_id))
    features = fact_features(y[cut * CFG.hop_length :], bpm, CFG)
    fpm = 60.0 / bpm * 4 * FPS
    estimate = estimate_downbeat(
        features["onset_env"], bpm, FPS, 4, features["beats"], features["chroma_cens"]
    )
    truth = (-cut) % fpm
    assert abs(_cyclic_error(estimate.phase_frames, truth, fpm)) <= 1.0, estimate
    assert -0.5 <= estimate.phase_frames < fpm - 0.5
    assert estimate.tracked_beats_used >= 10


def test_onset_strength_alone_would_pick_the_snare_beat():
    """Why the measure-level choice uses harmonic change: on this music the snare (beats 2
    and 4) has more onset strength than the kick on beat 1, so the onset-only fallback is a
    beat off, while the chroma change finds beat 1."""
    bpm = 120
    features = fact_features(synth_dance_music(bpm, 24.0, sr=CFG.sr, seed=2), bpm, CFG)
    with_chroma = estimate_downbeat(
        features["onset_env"], bpm, FPS, 4, features["beats"], features["chroma_cens"]
    )
    onset_only = estimate_downbeat(features["onset_env"], bpm, FPS, 4, features["beats"])
    assert with_chroma.downbeat_beat == 0
    assert onset_only.downbeat_beat != 0


def test_wrap_and_sequence_phase():
    assert wrap_phase(-0.2, 120.0) == pytest.approx(-0.2)
    assert wrap_phase(119.7, 120.0) == pytest.approx(-0.3)
    assert wrap_phase(250.0, 120.0) == pytest.approx(10.0)
    # A sequence starting 50 frames into the track sees the track's downbeat 50 frames earlier.
    assert sequence_phase(10.0, 50, 120.0) == pytest.approx(80.0)


def _old_measure_bounds(n_frames, bpm, fps, beats_per_measure, phase):
    """measure_bounds as it was before --phase auto (git 509bb0d), transcribed."""
    fpm = 60.0 / bpm * beats_per_measure * fps
    if n_frames <= 0 or fpm > n_frames + 1:
        return np.zeros((0, 2), dtype=np.int64)
    k_min = max(0, math.floor((-phase - 0.5) / fpm) - 1)
    k_max = int(math.ceil((n_frames - phase) / fpm)) + 1
    k = np.arange(k_min, max(k_max, k_min), dtype=np.float64)
    starts = np.floor(phase + k * fpm + 0.5).astype(np.int64)
    stops = np.floor(phase + (k + 1) * fpm + 0.5).astype(np.int64)
    keep = (starts >= 0) & (stops <= n_frames) & (stops > starts)
    return np.stack([starts[keep], stops[keep]], axis=1)


@pytest.mark.parametrize("phase", [0.0, 0.5, 3.25, -7.0, 159.6])
def test_measure_grid_keeps_the_old_bounds_and_adds_exact_ones(phase):
    for n_frames, bpm, fps in [(2000, 90.0, 60.0), (1799, 117.0, 60.0), (777, 133.3, 30.0)]:
        bounds, exact = measure_grid(n_frames, bpm, fps, 4, phase)
        old = _old_measure_bounds(n_frames, bpm, fps, 4, phase)
        assert bounds.dtype == old.dtype and np.array_equal(bounds, old)
        assert np.array_equal(measure_bounds(n_frames, bpm, fps, 4, phase), old)
        fpm = 60.0 / bpm * 4 * fps
        k = np.rint((exact[:, 0] - phase) / fpm)
        np.testing.assert_allclose(exact[:, 0], phase + k * fpm, rtol=0, atol=1e-9)
        np.testing.assert_allclose(exact[:, 1] - exact[:, 0], fpm, rtol=0, atol=1e-9)
        assert np.all(np.abs(bounds - exact) <= 0.5)


@pytest.fixture(scope="module")
def featurized(tmp_path_factory):
    """4 synthetic AIST++ sequences (3 songs): v1 ingest, v2 featurize (FACT audio only)."""
    root = tmp_path_factory.mktemp("downbeat")
    raw, store = root / "raw", root / "store"
    run_cli("synth", "aist", str(raw), "--sequences", "4", "-q")
    run_cli("ingest", "aist", str(raw), "--store", str(store), "-q")
    run_cli("featurize", str(store), "-q", "--audio-families", "fact")
    return store


def _copy(store, tmp_path):
    target = tmp_path / "store"
    shutil.copytree(store, target)
    return target


@pytest.mark.slow
def test_phase_auto_on_the_synthetic_twin(featurized, tmp_path):
    store = _copy(featurized, tmp_path)
    out = json.loads(run_cli("segment", str(store), "--phase", "auto", "--json").stdout)
    tracks = out["counts"]["phase"]
    music = pq.read_table(store / "versions/v2/music.parquet").to_pylist()
    assert sorted(tracks) == sorted(m["music_id"] for m in music)
    for music_id, track in tracks.items():
        fpm = 60.0 / track["bpm"] * 4 * FPS
        # Every synthetic track starts on a downbeat: phase 0 is the truth.
        assert abs(_cyclic_error(track["phase_frames"], 0.0, fpm)) <= 2.0, (music_id, track)
        assert track["phase_s"] == pytest.approx(track["phase_frames"] / FPS, abs=1e-6)
    manifest = json.loads((store / f"versions/{out['version']}/manifest.json").read_text())
    assert manifest["config"]["phase_frames"] == "auto"
    assert manifest["config"]["phase_method"]["method"].startswith("onset-grid")
    assert manifest["counts"]["phase"] == tracks
    rows = pq.read_table(store / f"versions/{out['version']}/measures.parquet").to_pylist()
    sequences = {
        s["seq_id"]: s for s in pq.read_table(store / "versions/v2/sequences.parquet").to_pylist()
    }
    for row in rows:
        seq = sequences[row["seq_id"]]
        expected_phase = tracks[seq["music_id"]]["phase_frames"]  # audio_offset 0
        assert row["phase_frames"] == pytest.approx(expected_phase)
        assert row["frame_start"] == math.floor(row["time_start_exact"] * FPS + 0.5)
        assert row["time_start"] == row["frame_start"] / FPS
    again = run_cli("segment", str(store), "--version", "v2", "--phase", "auto").stdout
    assert "nothing to do" in again
    # Human output names each track and how far the phase moved (3 beats a measure: new run).
    human = run_cli(
        "segment", str(store), "--version", "v2", "--phase", "auto", "--beats-per-measure", "3"
    ).stdout
    assert sum("downbeat at frame" in line for line in human.splitlines()) == len(tracks)
    run_cli("validate", str(store))


@pytest.mark.slow
def test_phase_zero_is_what_segment_always_wrote(featurized, tmp_path):
    store = _copy(featurized, tmp_path)
    out = json.loads(run_cli("segment", str(store), "--json").stdout)
    version = store / "versions" / out["version"]
    manifest = json.loads((version / "manifest.json").read_text())
    # The config (and with it the fingerprint) is the one segment recorded before --phase auto.
    assert manifest["config"] == {
        "beats_per_measure": 4,
        "phase_frames": 0.0,
        "formula": "fpm = 60/bpm*beats_per_measure*fps; "
        "[floor(phase+k*fpm+0.5), floor(phase+(k+1)*fpm+0.5)), complete measures only",
    }
    table = pq.read_table(version / "measures.parquet")
    sequences = pq.read_table(store / "versions/v2/sequences.parquet").to_pylist()
    expected = []
    for seq in sequences:
        for k, (a, b) in enumerate(
            _old_measure_bounds(seq["n_frames"], seq["bpm"], seq["fps"], 4, 0.0).tolist()
        ):
            expected.append((seq["seq_id"], k, a, b, a / seq["fps"], b / seq["fps"], seq["bpm"]))
    old_columns = ["seq_id", "measure", "frame_start", "frame_stop", "time_start", "time_stop"]
    got = table.select([*old_columns, "bpm"])
    assert table.schema.names[:7] == [*old_columns, "bpm"]
    assert [tuple(r.values()) for r in got.to_pylist()] == expected
    assert "phase_frames" not in table.schema.names
    exact = table.select(["time_start_exact", "time_stop_exact"]).to_pylist()
    for row, ex in zip(got.to_pylist(), exact, strict=True):
        assert abs(row["time_start"] - ex["time_start_exact"]) <= 0.5 / FPS + 1e-12
        assert ex["time_stop_exact"] - ex["time_start_exact"] == pytest.approx(240.0 / row["bpm"])
    assert "phase" not in manifest["counts"]


@pytest.mark.slow
def test_phase_auto_without_music_features_is_one_line_error(tmp_path):
    raw, store = tmp_path / "raw", tmp_path / "store"
    run_cli("synth", "aist", str(raw), "--sequences", "1", "-q")
    run_cli("ingest", "aist", str(raw), "--store", str(store), "-q")
    proc = run_cli("segment", str(store), "--phase", "auto", check=False)
    assert proc.returncode == 1
    lines = proc.stderr.strip().splitlines()
    assert len(lines) == 1 and "--phase auto needs the music features" in lines[0]
    assert sorted(p.name for p in (store / "versions").iterdir()) == ["v1"]
