"""Unit tests of the metrics (docs/EXPERIMENTS.md §7.1): closed forms, hand examples, identities."""

from __future__ import annotations

import math

import numpy as np
import pytest

from dancedata.metrics import (
    bas_msd,
    beat_counts,
    diversity,
    fid,
    fmd,
    fpd,
    frechet_distance,
    greedy_beat_matching,
    mean_over_units,
    mse,
)
from dancedata.metrics.fpd import pose_frames, pose_triples
from dancedata.metrics.frechet import moments
from dancedata.metrics.reconstruction_error import mse_euler75

# ----------------------------------------------------------------------------------------- mse


def test_mse_zero_for_identical_inputs() -> None:
    x = np.random.default_rng(0).normal(size=(10, 75))
    result = mse([x], [x.copy()])
    assert result.value == 0.0
    assert result.convention == {"space": "euler75", "J": 25, "wrap": False, "reduce": "pooled"}
    assert (result.n_units, result.n_frames) == (1, 10)


def test_mse_two_frame_toy_by_hand() -> None:
    truth = np.zeros((2, 75))
    recon = np.zeros((2, 75))
    recon[0, 0:3] = [1.0, 2.0, 2.0]  # translation block: |(1,2,2)|² = 9
    recon[1, 3] = 0.5  # first Euler angle: 0.25
    recon[1, 74] = -1.0  # last Euler angle: 1
    # Σ = 9 + 0.25 + 1 = 10.25 over N·J = 2·25 frames·blocks
    assert mse([truth], [recon]).value == pytest.approx(10.25 / 50, abs=1e-15)
    # euler72 drops the translation: (0.25 + 1) / (2·24)
    assert mse([truth], [recon], space="euler72").value == pytest.approx(1.25 / 48, abs=1e-15)


def test_mse_wrap_maps_two_pi_minus_eps_to_eps() -> None:
    eps = 1e-3
    truth = np.zeros((1, 75))
    recon = np.zeros((1, 75))
    recon[0, 10] = 2 * np.pi - eps
    recon[0, 1] = 2 * np.pi - eps  # translation: never wrapped
    raw = mse([truth], [recon]).value
    wrapped = mse([truth], [recon], wrap=True).value
    assert raw == pytest.approx(2 * (2 * np.pi - eps) ** 2 / 25)
    assert wrapped == pytest.approx(((2 * np.pi - eps) ** 2 + eps**2) / 25, rel=1e-12)
    assert mse([truth], [recon], wrap=True).convention["wrap"] is True


def test_mse_pooled_matches_reconstruction_error_module_and_reductions_differ() -> None:
    rng = np.random.default_rng(1)
    truth = [rng.normal(size=(n, 75)) for n in (5, 9, 14)]
    recon = [
        t + rng.normal(scale=s, size=t.shape) for t, s in zip(truth, (0.1, 1.0, 3.0), strict=True)
    ]
    pooled = mse(truth, recon).value
    expected = mse_euler75(np.concatenate(truth), np.concatenate(recon))
    assert pooled == pytest.approx(expected, rel=1e-12)
    assert mse(truth, recon, wrap=True).value == pytest.approx(
        mse_euler75(np.concatenate(truth), np.concatenate(recon), wrap=True), rel=1e-12
    )
    per_unit = [np.sum((r - t) ** 2) / (len(t) * 25) for t, r in zip(truth, recon, strict=True)]
    assert mse(truth, recon, reduce="measure_mean").value == pytest.approx(np.mean(per_unit))
    seq = mse(truth, recon, reduce="sequence_mean", groups=["a", "a", "b"]).value
    a = (np.sum((recon[0] - truth[0]) ** 2) + np.sum((recon[1] - truth[1]) ** 2)) / (14 * 25)
    assert seq == pytest.approx((a + per_unit[2]) / 2)


def test_mse_rotmat_ignores_padding_and_rejects_wrong_shapes() -> None:
    truth = np.zeros((3, 225))
    recon = np.zeros((3, 225))
    recon[:, :6] = 5.0  # padding
    recon[0, 9] = 1.0
    assert mse([truth], [recon], space="rotmat").value == pytest.approx(1.0 / 75)
    with pytest.raises(ValueError, match="225"):
        mse([truth[:, :75]], [recon[:, :75]], space="rotmat")
    with pytest.raises(ValueError, match="Euler"):
        mse([truth], [recon], space="rotmat", wrap=True)


# ------------------------------------------------------------------------------------- frechet


def test_frechet_identical_sets_give_zero() -> None:
    x = np.random.default_rng(2).normal(size=(50, 8))
    result = frechet_distance(x, x.copy())
    assert abs(result.value) < 1e-6
    assert result.convention["normalize"] == "reference_zscore"
    assert result.convention["eps"] == 1e-6


def test_frechet_pure_mean_shift_gives_squared_norm() -> None:
    rng = np.random.default_rng(3)
    x = rng.normal(size=(200, 5)) @ rng.normal(size=(5, 5))
    delta = np.array([0.5, -1.0, 2.0, 0.0, 0.25])
    result = frechet_distance(x + delta, x, normalize=False)
    assert result.value == pytest.approx(float(delta @ delta), abs=1e-6)


def test_frechet_singular_covariance_stays_finite() -> None:
    rng = np.random.default_rng(4)
    a, b = rng.normal(size=(5, 20)), rng.normal(size=(6, 20))  # n < d: rank-deficient Σ
    result = frechet_distance(a, b)
    assert math.isfinite(result.value)
    assert result.value > 0


def test_frechet_normalize_uses_reference_stats_only() -> None:
    rng = np.random.default_rng(5)
    ref = rng.normal(loc=3.0, scale=[1.0, 10.0, 0.1], size=(40, 3))
    ev = rng.normal(loc=1.0, scale=[2.0, 1.0, 1.0], size=(30, 3))
    mean, std = ref.mean(axis=0), ref.std(axis=0) + 1e-10
    expected = frechet_distance((ev - mean) / std, (ref - mean) / std, normalize=False).value
    assert frechet_distance(ev, ref).value == pytest.approx(expected, rel=1e-12)
    # changing the evaluated set's scale must not change how the reference is normalised
    other = frechet_distance(ev * 7.0, ref).value
    mean2, std2 = ref.mean(axis=0), ref.std(axis=0) + 1e-10
    assert other == pytest.approx(
        frechet_distance((ev * 7 - mean2) / std2, (ref - mean2) / std2, normalize=False).value
    )
    # normalising by the evaluated set instead gives a different number
    e_mean, e_std = ev.mean(axis=0), ev.std(axis=0) + 1e-10
    wrong = frechet_distance((ev - e_mean) / e_std, (ref - e_mean) / e_std, normalize=False)
    assert abs(wrong.value - expected) > 1e-3


def test_frechet_constant_reference_column_hazard_and_drop_option() -> None:
    rng = np.random.default_rng(6)
    ref = rng.normal(size=(20, 4))
    ref[:, 2] = 0.5
    ev = rng.normal(size=(20, 4))
    exploding = frechet_distance(ev, ref)
    dropped = frechet_distance(ev, ref, drop_constant_ref_columns=True)
    assert exploding.value > 1e15
    assert dropped.details["dropped_columns"] == 1 and dropped.value < 100


def test_frechet_needs_two_samples() -> None:
    with pytest.raises(ValueError, match="2 samples"):
        frechet_distance(np.zeros((1, 3)), np.ones((4, 3)))


# ----------------------------------------------------------------------------------- beat msd


def test_bas_msd_hand_example() -> None:
    m2m, a2m = bas_msd(np.array([10, 30]), np.array([12, 40]))
    assert m2m == (2**2 + 10**2) / 2 == 52
    assert a2m == (2**2 + 10**2) / 2 == 52


def test_bas_msd_empty_sets_give_nan() -> None:
    assert all(math.isnan(v) for v in bas_msd(np.array([], int), np.array([3, 4])))
    assert all(math.isnan(v) for v in bas_msd(np.array([3]), np.array([], int)))


# ------------------------------------------------------------------------ coverage / hit rate


def test_greedy_matching_is_one_to_one_in_time_order() -> None:
    # motion 10 takes 11 (nearest); motion 12 would prefer 11 too, but it is taken: it gets 14
    # (within tol 3); motion 30 has nothing within 3 of it.
    pairs = greedy_beat_matching(np.array([12, 10, 30]), np.array([11, 14, 40]), tol=3)
    assert pairs == [(10, 11), (12, 14)]
    # a tie goes to the earlier music beat
    assert greedy_beat_matching(np.array([20]), np.array([22, 18]), tol=2) == [(20, 18)]
    # outside the tolerance nothing matches
    assert greedy_beat_matching(np.array([0]), np.array([5]), tol=4) == []


def _positions_with_stops(n_frames: int, stops: list[int]) -> np.ndarray:
    """A joint moving with speed |t − s| near each stop s: speed minima exactly at the stops."""
    t = np.arange(n_frames, dtype=np.float64)
    speed = np.min(np.abs(t[:, None] - np.array(stops)[None, :]), axis=1) + 0.1
    x = np.concatenate([[0.0], np.cumsum(speed[1:])])
    p = np.zeros((n_frames, 2, 3))
    p[:, 1, 0] = x
    return p


def test_coverage_hit_accuracy_hand_example() -> None:
    # motion beats (mint: minima of the displacement arriving at t) at 20, 50, 80
    positions = _positions_with_stops(100, [20, 50, 80])
    music = np.array([22, 30, 62, 79, 150])  # 150 is past the motion: ignored
    counts = beat_counts(positions, music, tol=3)
    # 20 ↔ 22 (2 ≤ 3), 50: nearest 62 is 12 away, 80 ↔ 79
    assert (counts.motion, counts.music, counts.aligned) == (3, 4, 2)
    assert counts.coverage == pytest.approx(3 / 4)
    assert counts.hit_rate == pytest.approx(2 / 3)
    assert counts.accuracy == pytest.approx(2 / 4)
    assert beat_counts(positions, music, tol=12).aligned == 3  # 50 ↔ 62 within 12


# ----------------------------------------------------------------------------------- fpd / fmd


def test_fpd_fmd_equal_inputs_give_zero() -> None:
    rng = np.random.default_rng(7)
    clips = [rng.normal(size=(300, 5, 3)) * 0.3 for _ in range(3)]  # 300 triples > 45 dims
    for parity in ("spec", "transflower"):
        assert abs(fpd(clips, [c.copy() for c in clips], parity=parity).value) < 1e-6
        assert abs(fmd(clips, [c.copy() for c in clips], parity=parity).value) < 1e-6


def test_transflower_parity_moments_and_triples_on_a_toy() -> None:
    clip_a = np.arange(7 * 2, dtype=np.float64).reshape(7, 2)
    clip_b = 100 + np.arange(5 * 2, dtype=np.float64).reshape(5, 2)
    pooled = pose_frames([clip_a, clip_b], frame_step=1)
    # uncentred second moment XᵀX / N
    mu, second = moments(pooled, "uncentred")
    np.testing.assert_allclose(second, pooled.T @ pooled / 12)
    np.testing.assert_allclose(mu, pooled.mean(axis=0))
    # non-overlapping triples over the pooled 12 frames (they straddle the two clips)
    triples = pose_triples([clip_a, clip_b], frame_step=1, parity="transflower")
    assert triples.shape == (4, 6)
    np.testing.assert_array_equal(triples[2], np.concatenate([clip_a[6], clip_b[0], clip_b[1]]))
    # sliding triples stay inside each clip: 5 + 3
    sliding = pose_triples([clip_a, clip_b], frame_step=1, parity="spec")
    assert sliding.shape == (8, 6)
    np.testing.assert_array_equal(sliding[1], np.concatenate(clip_a[1:4]))
    # the FPD value of the transflower path is the FD of those moments without ε
    gen = [clip_a * 1.1, clip_b - 1.0]
    result = fpd(gen, [clip_a, clip_b], frame_step=1, parity="transflower")
    g = pose_frames(gen, 1)
    m1, c1 = g.mean(axis=0), g.T @ g / len(g)
    m2, c2 = pooled.mean(axis=0), pooled.T @ pooled / len(pooled)
    from scipy.linalg import sqrtm

    expected = np.sum((m1 - m2) ** 2) + np.trace(c1) + np.trace(c2) - 2 * np.trace(sqrtm(c1 @ c2))
    assert result.value == pytest.approx(float(np.real(expected)), rel=1e-9)
    assert result.convention["moments"] == "uncentred" and result.convention["eps"] is None


def test_fpd_decimates_by_frame_step() -> None:
    clip = np.random.default_rng(8).normal(size=(30, 4))
    assert pose_frames([clip], frame_step=3).shape == (10, 4)
    np.testing.assert_array_equal(pose_frames([clip], 3), clip[::3])


# ------------------------------------------------------------------------- fid and diversity


def _walk(rng: np.random.Generator, n: int = 120) -> np.ndarray:
    return np.cumsum(rng.normal(scale=0.01, size=(n, 24, 3)), axis=0) + rng.normal(size=(24, 3))


def test_fid_identical_sets_zero_and_named() -> None:
    rng = np.random.default_rng(9)
    units = [_walk(rng) for _ in range(80)]  # more units than the 72 kinetic dims
    k = fid(units, units, "kinetic")
    g = fid(units, units, "geometric", drop_constant_ref_columns=True)
    assert k.name == "fid_k" and abs(k.value) < 1e-6
    assert g.name == "fid_g" and abs(g.value) < 1e-6
    assert k.convention["kinetic_mode"] == "parity" and k.n_units == 80
    # fewer units than dims: Σ is singular and scipy's sqrtm is only accurate to ~1e-5 here
    # (the same holds for mint's code, which this follows): still ~0, not exactly
    few = fid(units[:6], units[:6], "kinetic")
    assert abs(few.value) < 1e-4 and few.n_units == 6


def test_diversity_is_mean_pairwise_distance() -> None:
    pts = np.array([[0.0, 0.0], [3.0, 4.0], [0.0, 8.0]])
    assert diversity(pts).value == pytest.approx((5 + 8 + 5) / 3)
    assert math.isnan(diversity(pts[:1]).value)
    ref = np.array([[0.0, 0.0], [2.0, 2.0]])  # mean (1, 1), std (1, 1)
    scaled = diversity(pts, ref)
    assert scaled.value == pytest.approx((5 + 8 + 5) / 3 / (1 + 1e-10))


def test_mean_over_units_counts_undefined() -> None:
    r = mean_over_units("bas_mint", [0.5, float("nan"), 1.0], {"sigma": 3}, 300, skip_nan=True)
    assert r.value == pytest.approx(0.75) and r.n_units == 2 and r.details["n_undefined"] == 1
    assert math.isnan(mean_over_units("x", [1.0, float("nan")], {}, 0).value)
