"""Properties of the measure segmenter that tests/compute/test_measures.py does not cover: exact
measure lengths, prefix stability, the count formula, the segment rows built from a sequences
table, and bad tempo / fps / phase values (a clear ValueError, never a hang, a huge allocation or
a ZeroDivisionError)."""

from __future__ import annotations

import math
import time

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from dancedata.compute.measures import frames_per_measure, measure_bounds
from dancedata.featurize.segment import SegmentOptions, measure_rows

FPS = st.sampled_from([20.0, 24.0, 25.0, 29.97, 30.0, 60.0, 120.0])
BPM = st.floats(30.0, 300.0)


@pytest.mark.slow
@settings(max_examples=300, deadline=None)
@given(
    bpm=BPM,
    fps=FPS,
    n_frames=st.integers(0, 20000),
    beats=st.integers(1, 12),
    phase=st.floats(0.0, 200.0),
)
def test_each_measure_is_floor_or_ceil_of_fpm_and_the_count_is_exact(
    bpm, fps, n_frames, beats, phase
):
    bounds = measure_bounds(n_frames, bpm, fps, beats, phase)
    fpm = frames_per_measure(bpm, fps, beats)
    assert bounds.dtype == np.int64 and bounds.shape[1:] == (2,)
    lengths = bounds[:, 1] - bounds[:, 0]
    assert set(lengths.tolist()) <= {math.floor(fpm), math.ceil(fpm)}
    assert np.all(bounds[:, 0] >= 0) and np.all(bounds[:, 1] <= n_frames)
    # Count: every k whose rounded stop fits (starts are >= 0 since phase >= 0).
    expected = sum(
        1
        for k in range(int(n_frames / fpm) + 2)
        if math.floor(phase + (k + 1) * fpm + 0.5) <= n_frames
    )
    assert len(bounds) == expected


@settings(max_examples=200, deadline=None)
@given(
    bpm=BPM,
    fps=FPS,
    n_frames=st.integers(0, 5000),
    more=st.integers(0, 5000),
    phase=st.floats(-100.0, 100.0),
)
def test_a_longer_sequence_only_adds_measures_at_the_end(bpm, fps, n_frames, more, phase):
    short = measure_bounds(n_frames, bpm, fps, 4, phase)
    long = measure_bounds(n_frames + more, bpm, fps, 4, phase)
    assert np.array_equal(long[: len(short)], short)
    assert np.all(short[:, 0] >= 0)  # a negative phase drops the measures before frame 0


@settings(max_examples=100, deadline=None)
@given(
    bpm=st.one_of(
        st.just(0.0),
        st.floats(max_value=0.0),
        st.just(math.inf),
        st.just(-math.inf),
        st.just(math.nan),
        st.floats(1e7, 1e300),
    ),
    fps=FPS,
)
def test_impossible_tempi_are_a_clear_value_error_never_a_hang(bpm, fps):
    start = time.perf_counter()
    with pytest.raises(ValueError):
        measure_bounds(5000, bpm, fps)
    assert time.perf_counter() - start < 0.5


@settings(max_examples=50, deadline=None)
@given(
    fps=st.one_of(st.floats(max_value=0.0), st.just(math.nan), st.just(math.inf)),
    beats=st.integers(-3, 0),
)
def test_bad_fps_or_beats_are_a_value_error(fps, beats):
    with pytest.raises(ValueError):
        measure_bounds(1000, 120.0, fps)
    with pytest.raises(ValueError):
        measure_bounds(1000, 120.0, 60.0, beats)


@pytest.mark.parametrize("phase", [math.nan, math.inf, -math.inf])
def test_non_finite_phase_is_a_value_error(phase):
    with pytest.raises(ValueError):
        measure_bounds(1000, 120.0, 60.0, 4, phase)


def test_huge_sequences_are_segmented_quickly():
    start = time.perf_counter()
    bounds = measure_bounds(50_000_000, 137.0, 120.0)  # nearly 5 days of motion at 120 fps
    fpm = frames_per_measure(137.0, 120.0)  # 210.2 frames
    assert len(bounds) == math.floor((50_000_000 - 0.5) / fpm)
    assert time.perf_counter() - start < 2.0


_SEQ = st.fixed_dictionaries(
    {
        "n_frames": st.integers(0, 3000),
        "fps": FPS,
        "bpm": st.one_of(st.none(), st.just(0.0), st.just(math.nan), BPM),
    }
)


@settings(max_examples=200, deadline=None)
@given(seqs=st.lists(_SEQ, max_size=6), beats=st.integers(1, 8), phase=st.floats(0.0, 30.0))
def test_measure_rows_cover_each_sequence_with_numbered_in_range_measures(seqs, beats, phase):
    table = [{**s, "seq_id": f"s{i}"} for i, s in enumerate(seqs)]
    rows = measure_rows(table, SegmentOptions(beats_per_measure=beats, phase_frames=phase))
    by_seq: dict[str, list[dict]] = {}
    for row in rows:
        by_seq.setdefault(row["seq_id"], []).append(row)
    for seq in table:
        got = by_seq.get(seq["seq_id"], [])
        bpm = seq["bpm"]
        if bpm is None or not bpm > 0:
            assert got == []  # no tempo: no measures, and no crash
            continue
        assert [r["measure"] for r in got] == list(range(len(got)))
        for r in got:
            assert 0 <= r["frame_start"] < r["frame_stop"] <= seq["n_frames"]
            assert r["time_start"] == pytest.approx(r["frame_start"] / seq["fps"])
            assert r["time_stop"] == pytest.approx(r["frame_stop"] / seq["fps"])
            assert r["bpm"] == bpm
        expected = measure_bounds(seq["n_frames"], bpm, seq["fps"], beats, phase)
        assert [[r["frame_start"], r["frame_stop"]] for r in got] == expected.tolist()


@settings(max_examples=100, deadline=None)
@given(phase=st.floats(-1e12, 1e12), n_frames=st.integers(0, 100_000), bpm=BPM, fps=FPS)
def test_any_phase_costs_time_in_proportion_to_the_sequence_only(phase, n_frames, bpm, fps):
    start = time.perf_counter()
    bounds = measure_bounds(n_frames, bpm, fps, 4, phase)
    assert time.perf_counter() - start < 0.5
    assert np.all(bounds[:, 0] >= 0) and np.all(bounds[:, 1] <= n_frames)


@pytest.mark.parametrize("phase", [1e13, -1e13, 1e300])
def test_absurd_phase_is_a_value_error(phase):
    with pytest.raises(ValueError, match="phase"):
        measure_bounds(1000, 120.0, 60.0, 4, phase)
