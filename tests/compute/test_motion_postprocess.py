"""Post-processing of generated motion: the zero-phase Butterworth low-pass against scipy and the
closed-form gain of a forward-backward Butterworth filter, no lag, rotations smoothed without
sign artefacts, and planted root flips restored exactly."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.signal import butter, filtfilt
from scipy.spatial.transform import Rotation

from dancedata.compute.motion_postprocess import postprocess_config, postprocess_motion
from dancedata.compute.smoothing import butterworth_gain, butterworth_lowpass, smooth_axis_angle

FPS = 60.0


def _fit_sine(y: np.ndarray, t: np.ndarray, freq: float) -> tuple[float, float]:
    """Amplitude and phase (rad) of the least-squares sine of ``freq`` Hz in ``y``."""
    basis = np.stack([np.sin(2 * np.pi * freq * t), np.cos(2 * np.pi * freq * t)], axis=1)
    (a, b), *_ = np.linalg.lstsq(basis, y, rcond=None)
    return float(np.hypot(a, b)), float(np.arctan2(b, a))


def _closed_form_gain(freq: float, cutoff: float, order: int) -> float:
    """|H(f)|² of the bilinear-transform Butterworth filter (filtered forward and backward)."""
    return 1.0 / (1.0 + (np.tan(np.pi * freq / FPS) / np.tan(np.pi * cutoff / FPS)) ** (2 * order))


@pytest.mark.parametrize("order", [1, 2, 3])
@pytest.mark.parametrize("freq", [1.5, 4.0, 9.0, 15.0])
def test_sine_gain_is_the_closed_form_and_phase_is_zero(order, freq):
    cutoff = 4.0
    t = np.arange(2400) / FPS  # 40 s: whole cycles of every frequency tested
    x = np.sin(2 * np.pi * freq * t)
    y = butterworth_lowpass(x, FPS, cutoff, order)
    b, a = butter(order, cutoff, fs=FPS)
    np.testing.assert_allclose(y, filtfilt(b, a, x), atol=1e-9)  # scipy called directly
    inner = slice(600, -600)  # far from the padded ends
    amplitude, phase = _fit_sine(y[inner], t[inner], freq)
    expected = _closed_form_gain(freq, cutoff, order)
    assert amplitude == pytest.approx(expected, rel=1e-3, abs=1e-6)
    assert butterworth_gain(freq, FPS, cutoff, order) == pytest.approx(expected, rel=1e-12)
    if expected > 1e-3:
        assert abs(phase) < 1e-3  # zero phase: no lag
    if freq < cutoff / 2:
        assert amplitude > 0.85  # passed (order 1 at 1.5 Hz: 0.88)
    if freq > 2 * cutoff:
        assert amplitude < 0.15  # attenuated (order 1 at 9 Hz: 0.148)
    assert butterworth_gain(cutoff, FPS, cutoff, order) == pytest.approx(0.5)


def test_no_lag_on_a_pulse():
    x = np.zeros(601)
    x[300] = 1.0
    y = butterworth_lowpass(x, FPS, 3.0, 2)
    assert int(np.argmax(y)) == 300
    np.testing.assert_allclose(y[300 - 50 : 300], y[301:351][::-1], atol=1e-12)  # symmetric


def _yaw_rotvecs(angle: np.ndarray) -> np.ndarray:
    return np.stack([np.zeros_like(angle), angle, np.zeros_like(angle)], axis=-1)


def test_smooth_axis_angle_passes_slow_turns_and_crosses_pi():
    t = np.arange(600) / FPS
    angle = 2.5 + 0.8 * np.sin(2 * np.pi * 0.3 * t)  # through π and back: axis-angle jumps
    rot = Rotation.from_rotvec(_yaw_rotvecs(angle))
    jitter = 0.02 * np.sin(2 * np.pi * 20 * t)
    noisy = rot * Rotation.from_rotvec(_yaw_rotvecs(jitter))
    smooth = smooth_axis_angle(noisy.as_rotvec()[:, None, :], FPS, 4.0, 2)[:, 0]
    err = np.degrees((Rotation.from_rotvec(smooth) * rot.inv()).magnitude())
    inner = slice(60, -60)
    assert err[inner].max() < 0.05  # 20 Hz jitter of about 1° removed, the slow turn kept
    assert np.degrees(np.abs(jitter)).max() > 0.99
    # the constant rotation is a fixed point
    still = np.tile([[0.1, 2.9, -0.2]], (50, 1))[:, None, :]
    np.testing.assert_allclose(smooth_axis_angle(still, FPS, 4.0), still, atol=1e-12)


def _constant_velocity_root(n: int = 240) -> Rotation:
    omega = np.array([0.01, 0.03, -0.005])  # rad per frame
    start = Rotation.from_rotvec([0.3, -1.0, 0.2])
    return Rotation.from_rotvec(np.arange(n)[:, None] * omega) * start


@pytest.mark.parametrize("axis", [(0, 1, 0), (0.4, 1, -0.3), (1, 0, 0)])
def test_planted_hip_flips_are_restored_exactly(axis):
    root = _constant_velocity_root()
    half = Rotation.from_rotvec(np.pi * np.asarray(axis, float) / np.linalg.norm(axis))
    spans = [(30, 41), (100, 101), (150, 200)]
    flipped = root.as_rotvec()
    for a, b in spans:
        flipped[a:b] = (half * root[a:b]).as_rotvec()
    rng = np.random.default_rng(1)
    others = rng.normal(0, 0.3, (len(flipped), 23, 3))
    trans = rng.normal(0, 1, (len(flipped), 3))
    axis_angle = np.concatenate([flipped[:, None, :], others], axis=1)
    out = postprocess_motion(axis_angle, trans, None, FPS, repair_flips=True)
    assert out.flips is not None and out.flips.runs == spans
    error = np.degrees((Rotation.from_rotvec(out.axis_angle[:, 0]) * root.inv()).magnitude())
    assert error.max() < 1e-9  # exactly, to rounding
    np.testing.assert_array_equal(out.axis_angle[:, 1:], others)  # only the root is touched
    np.testing.assert_array_equal(out.trans, trans)
    assert out.flips.frames.size == 11 + 1 + 50


def test_repair_then_smooth_and_refusals():
    root = _constant_velocity_root()
    flipped = root.as_rotvec()
    half = Rotation.from_rotvec([0, np.pi, 0])
    flipped[50:60] = (half * root[50:60]).as_rotvec()
    axis_angle = flipped[:, None, :]
    out = postprocess_motion(axis_angle, None, None, FPS, smooth_cutoff_hz=5.0, repair_flips=True)
    error = np.degrees((Rotation.from_rotvec(out.axis_angle[:, 0]) * root.inv()).magnitude())
    assert error.max() < 0.5  # repaired before smoothing: no smeared half turn
    assert error[20:-20].max() < 0.05  # (the largest errors are the padded ends')
    positions = np.zeros((10, 24, 3))
    with pytest.raises(ValueError, match="positions only"):
        postprocess_motion(None, None, positions, FPS, repair_flips=True)
    with pytest.raises(ValueError, match="cutoff"):
        postprocess_motion(axis_angle, None, None, FPS, smooth_cutoff_hz=40.0)
    config = postprocess_config(6.0, 2, True, 90.0)
    assert config["smoothing"]["effective_order"] == 4
    assert config["hip_flips"]["threshold_deg_per_frame"] == 90.0
    assert postprocess_config(None, 2, False, 90.0)["smoothing"] is None
