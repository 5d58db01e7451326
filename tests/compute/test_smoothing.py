"""Butterworth zero-phase smoothing: agrees with scipy's filtfilt, has no wrap-around artefacts
on angles crossing ±180° or on quaternion sign flips."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.signal import butter, filtfilt
from scipy.spatial.transform import Rotation

from dancedata.compute.smoothing import butterworth_lowpass, smooth_euler, smooth_quaternions

FPS = 120.0


@pytest.mark.parametrize("order", [1, 2, 4])
def test_lowpass_equals_filtfilt(order):
    x = np.random.default_rng(order).normal(size=(300, 5))
    b, a = butter(order, 6.0, fs=FPS)
    expected = filtfilt(b, a, x, axis=0)
    np.testing.assert_allclose(butterworth_lowpass(x, FPS, 6.0, order), expected, atol=1e-9)


def test_lowpass_passes_slow_and_removes_fast_without_lag():
    t = np.arange(600) / FPS
    slow = np.sin(2 * np.pi * 0.5 * t)
    fast = 0.3 * np.sin(2 * np.pi * 30 * t)
    out = butterworth_lowpass(slow + fast, FPS, 4.0, order=2)
    inner = slice(60, -60)
    assert np.abs(out[inner] - slow[inner]).max() < 0.01
    # Zero phase: the peak of the slow wave stays on the same frame.
    assert np.argmax(out[:240]) == np.argmax(slow[:240])


def test_lowpass_short_clips_and_bad_parameters():
    np.testing.assert_array_equal(butterworth_lowpass(np.ones((1, 3)), FPS, 5), np.ones((1, 3)))
    np.testing.assert_allclose(butterworth_lowpass(np.ones((4, 3)), FPS, 5), np.ones((4, 3)))
    with pytest.raises(ValueError):
        butterworth_lowpass(np.ones(10), FPS, 60.0)
    with pytest.raises(ValueError):
        butterworth_lowpass(np.ones(10), FPS, 5.0, order=0)


def _crossing_curve() -> tuple[np.ndarray, np.ndarray]:
    """A yaw angle rising through +180° (wrapped to -180°) with a little noise."""
    t = np.arange(240) / FPS
    rng = np.random.default_rng(0)
    true = np.pi - 0.5 + 0.5 * t + 0.002 * rng.normal(size=t.shape)
    return true, (true + np.pi) % (2 * np.pi) - np.pi


def _wrapped_difference(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    return np.abs((a - b + np.pi) % (2 * np.pi) - np.pi)


def test_euler_smoothing_has_no_spike_at_the_wrap():
    true, wrapped = _crossing_curve()
    assert np.abs(np.diff(wrapped)).max() > 6  # the input jumps by 2π
    smooth = smooth_euler(wrapped[:, None], FPS, 5.0, order=2)[:, 0]
    assert np.all((smooth >= -np.pi) & (smooth < np.pi))
    assert _wrapped_difference(smooth, true).max() < 0.01
    # A naive filter on the wrapped curve rings around the wrap: the check above can fail.
    naive = butterworth_lowpass(wrapped, FPS, 5.0, order=2)
    assert _wrapped_difference(naive, true).max() > 0.5
    unwrapped = smooth_euler(wrapped[:, None], FPS, 5.0, wrap=False)[:, 0]
    assert np.abs(np.diff(unwrapped)).max() < 0.05


def test_quaternion_smoothing_ignores_sign_flips_and_stays_unit():
    true, _ = _crossing_curve()
    rots = Rotation.from_euler("ZYX", np.stack([true, 0.3 * np.ones_like(true), 0.1 * true], 1))
    quat = rots.as_quat()[:, [3, 0, 1, 2]]
    flips = np.random.default_rng(1).choice([-1.0, 1.0], size=(len(quat), 1))
    smooth = smooth_quaternions(quat * flips, FPS, 5.0)
    reference = smooth_quaternions(quat, FPS, 5.0)
    assert np.abs(np.abs(np.sum(smooth * reference, axis=1)) - 1).max() < 1e-12
    np.testing.assert_allclose(np.linalg.norm(smooth, axis=-1), 1.0, atol=1e-12)
    err = (Rotation.from_quat(smooth[:, [1, 2, 3, 0]]) * rots.inv()).magnitude()
    assert err.max() < 0.01
    # (F, J, 4) shapes work per joint.
    stacked = np.stack([quat * flips, quat], axis=1)
    assert smooth_quaternions(stacked, FPS, 5.0).shape == stacked.shape
