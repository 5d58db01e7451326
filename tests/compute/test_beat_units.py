"""Beats and phrases as units: the tempo grid against the measures it subdivides and a brute-force
enumeration, phrases against the measures table, re-timing a motion retimed by a known factor
back onto the music beats, ChoreoGraph's 4 s segments, and ``segment --tables`` on a real store."""

from __future__ import annotations

import json

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

import dancedata
from dancedata.compute.beat_units import (
    beat_grid,
    choreograph_segments,
    nearest_beats,
    phrase_bounds,
    retime_positions,
    retime_quaternions,
)
from dancedata.compute.measures import measure_bounds
from tests.helpers import run_cli


@pytest.mark.parametrize(
    "n,bpm,fps,phase", [(600, 120, 60, 0.0), (1234, 97.3, 30, 7.4), (400, 180, 20, -3.0)]
)
def test_beat_grid_brute_force_and_measures(n, bpm, fps, phase):
    grid = beat_grid(n, bpm, fps, 4, phase)
    fpb = 60 / bpm * fps
    brute = [
        (j, int(np.floor(phase + j * fpb + 0.5)))
        for j in range(0, 10_000)
        if 0 <= np.floor(phase + j * fpb + 0.5) < n
    ]
    assert grid["beat"].tolist() == [j for j, _ in brute]
    assert grid["frame"].tolist() == [f for _, f in brute]
    # every complete measure starts on a downbeat of the grid, and holds 4 beats
    for start, stop in measure_bounds(n, bpm, fps, 4, phase).tolist():
        inside = (grid["frame"] >= start) & (grid["frame"] < stop)
        assert grid["frame"][grid["downbeat"] & inside].tolist() == [start]
        assert inside.sum() == 4
        assert grid["beat_in_measure"][inside].tolist() == [0, 1, 2, 3]


def test_phrase_bounds_group_whole_measures():
    bounds = measure_bounds(2000, 120, 60, 4)  # 16 measures of 120 frames
    phrases = phrase_bounds(bounds, 4)
    assert phrases.tolist() == [[k * 4, k * 4 + 4, k * 480, k * 480 + 480] for k in range(4)]
    assert phrase_bounds(bounds, 8).shape == (2, 4)
    assert phrase_bounds(bounds[:7], 8).shape == (0, 4)


def test_retime_recovers_a_motion_retimed_by_a_known_factor():
    """A motion with beats every 40 frames, played 1.25× slower (beats every 50 frames), is
    re-timed from its motion beats onto music beats 40 frames apart: the original comes back
    (exactly at the beats, to interpolation error between)."""
    fps = 60.0
    t = np.arange(0, 161)  # 4 beats of 40 frames
    base = np.stack([np.sin(2 * np.pi * t / 80), np.cos(2 * np.pi * t / 160), t / 160], axis=1)
    slow_t = np.arange(0, 201) / 1.25  # the same motion, 1.25× slower: 200 frames
    slow = np.stack(
        [np.sin(2 * np.pi * slow_t / 80), np.cos(2 * np.pi * slow_t / 160), slow_t / 160], axis=1
    )[:, None, :]
    back = retime_positions(slow, (0, 200), (0, 160))[:, 0]
    assert back.shape == (161, 3)
    np.testing.assert_allclose(back[::40], base[::40], atol=1e-12)
    np.testing.assert_allclose(back, base, atol=2e-3)
    # rotations: SLERP keeps unit norm and lands on the beat frames exactly
    rot = Rotation.from_rotvec(slow[:, 0] * 0.5)
    quat = np.roll(rot.as_quat(), 1, axis=1)[:, None, :]
    retimed = retime_quaternions(quat, (0, 200), (0, 160))
    np.testing.assert_allclose(np.linalg.norm(retimed, axis=-1), 1.0, atol=1e-12)
    np.testing.assert_allclose(retimed[::40, 0], quat[::50, 0], atol=1e-12)
    _ = fps


def test_nearest_beats_and_choreograph_segments():
    assert nearest_beats(np.array([0, 9, 10, 26]), np.array([5, 15, 25])).tolist() == [5, 5, 5, 25]
    fps = 60.0
    music = np.arange(0, 1800, 30)  # 120 BPM at 60 fps, 30 s
    motion = music[::2] + 3  # the dancer hits every other beat, 3 frames late
    seg = choreograph_segments(music, motion, fps, segment_s=4.0)
    assert seg["music_start"][0] == 0
    assert np.all(seg["music_stop"] - seg["music_start"] == 240)  # 8 beats = 4 s
    assert np.all(seg["n_music_beats"] == 8)
    np.testing.assert_array_equal(seg["motion_start"], seg["music_start"] + 3)
    np.testing.assert_allclose(seg["tempo_ratio"], 1.0)
    assert len(seg["music_start"]) == 7  # 7 whole 4 s segments from beat 0 to beat 56


@pytest.fixture(scope="module")
def store(tmp_path_factory):
    root = tmp_path_factory.mktemp("units")
    raw, store = root / "raw", root / "store"
    run_cli("synth", "aist", str(raw), "--sequences", "3", "--seed", "4", "--quiet")
    run_cli("ingest", "aist", str(raw), "--store", str(store), "--quiet")
    return store


@pytest.mark.slow
def test_segment_tables_beats_and_phrases(store):
    plain = json.loads(run_cli("segment", str(store), "--json").stdout)
    out = run_cli(
        "segment",
        str(store),
        "--tables",
        "measures,beats,phrases",
        "--phrase-measures",
        "2",
        "--json",
        "--version",
        plain["version"],
    )
    version = json.loads(out.stdout)["version"]
    assert version != plain["version"]
    ds = dancedata.open_store(store)
    beats = ds.table("beats").to_pylist()
    phrases = ds.table("phrases").to_pylist()
    measures = ds.table("measures").to_pylist()
    for seq_id in ds.seq_ids():
        seq = ds.sequence(seq_id)
        mine = [b for b in beats if b["seq_id"] == seq_id]
        grid = beat_grid(seq["n_frames"], seq["bpm"], seq["fps"], 4, 0.0)
        assert [b["frame"] for b in mine] == grid["frame"].tolist()
        starts = [m["frame_start"] for m in measures if m["seq_id"] == seq_id]
        downs = [b["frame"] for b in mine if b["downbeat"]]
        assert starts == downs[: len(starts)]
        ph = [p for p in phrases if p["seq_id"] == seq_id]
        assert len(ph) == len(starts) // 2
        assert all(p["measure_stop"] - p["measure_start"] == 2 for p in ph)
    run_cli("validate", str(store))
    bad = run_cli("segment", str(store), "--tables", "bars", check=False)
    assert bad.returncode == 1 and "unknown segment table(s) bars" in bad.stderr
