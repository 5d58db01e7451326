"""Measure boundaries by the contract's formula, and their properties for any tempo."""

from __future__ import annotations

import math

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from dancedata.compute.measures import frames_per_measure, measure_bounds


def test_aist_real_case():
    # 100 BPM at 60 fps: 144 frames per measure; a 576-frame basic piece holds exactly 4.
    bounds = measure_bounds(576, 100.0, 60.0)
    assert bounds.tolist() == [[0, 144], [144, 288], [288, 432], [432, 576]]
    assert measure_bounds(575, 100.0, 60.0).shape[0] == 3


def test_fractional_measure_rounds_per_boundary():
    # 135 BPM at 60 fps: 106.666... frames per measure.
    fpm = frames_per_measure(135.0, 60.0)
    bounds = measure_bounds(1000, 135.0, 60.0)
    expected = [
        [math.floor(k * fpm + 0.5), math.floor((k + 1) * fpm + 0.5)]
        for k in range(9)
        if math.floor((k + 1) * fpm + 0.5) <= 1000
    ]
    assert bounds.tolist() == expected


@settings(max_examples=300, deadline=None)
@given(
    bpm=st.floats(40, 240),
    fps=st.sampled_from([20.0, 24.0, 25.0, 30.0, 60.0, 120.0]),
    n_frames=st.integers(0, 5000),
    beats=st.integers(2, 7),
    phase=st.floats(0, 50),
)
def test_bounds_cover_exactly_the_complete_measures(bpm, fps, n_frames, beats, phase):
    bounds = measure_bounds(n_frames, bpm, fps, beats, phase)
    fpm = 60.0 / bpm * beats * fps
    if len(bounds):
        assert np.all(bounds[1:, 0] == bounds[:-1, 1])  # contiguous
        assert bounds[0, 0] == math.floor(phase + 0.5)
        assert bounds[-1, 1] <= n_frames
        lengths = bounds[:, 1] - bounds[:, 0]
        assert np.all(np.abs(lengths - fpm) <= 1.0)
    # The next measure would not fit: no complete measure is left out.
    k = len(bounds)
    assert math.floor(phase + (k + 1) * fpm + 0.5) > n_frames
