"""How precise a Fréchet distance is when there are fewer units than feature dimensions.

The covariances are then singular and Σ1 Σ2 has exactly-zero eigenvalues, where the matrix square
root is not differentiable: two correct sqrtm implementations (SciPy versions, or the
eigendecomposition written here) may disagree by up to ``details["sqrtm_error_bound"]``
(``dancedata.metrics.frechet.sqrtm_error_bound``). The exact value is computed
independently through the symmetric form Tr (Σ1 Σ2)^{1/2} = Σ √eig(H Σ2 H), H = Σ1^{1/2}
(numpy ``eigh``, no sqrtm).
"""

from __future__ import annotations

import numpy as np
import pytest
from scipy import linalg

from dancedata.metrics.frechet import (
    IMAG_TOLERANCE,
    frechet_distance,
    frechet_distance_from_moments,
    sqrtm_error_bound,
)


def exact_fd(x: np.ndarray, r: np.ndarray) -> float:
    """FD of the raw features' moments (no normalisation) via symmetric eigendecompositions."""
    mu1, mu2 = x.mean(axis=0), r.mean(axis=0)
    s1, s2 = np.cov(x, rowvar=False), np.cov(r, rowvar=False)
    w, v = np.linalg.eigh(s1)
    half = (v * np.sqrt(np.clip(w, 0.0, None))) @ v.T
    trace = np.sqrt(np.clip(np.linalg.eigvalsh(half @ s2 @ half), 0.0, None)).sum()
    return float((mu1 - mu2) @ (mu1 - mu2) + np.trace(s1) + np.trace(s2) - 2.0 * trace)


def eig_sqrtm_fd(x: np.ndarray, r: np.ndarray) -> float:
    """FD with another sqrtm: A = V diag(λ) V⁻¹ → V diag(√λ) V⁻¹ (numpy ``eig``)."""
    mu1, mu2 = x.mean(axis=0), r.mean(axis=0)
    s1, s2 = np.cov(x, rowvar=False), np.cov(r, rowvar=False)
    lam = np.linalg.eigvals(s1 @ s2).astype(complex)
    return float((mu1 - mu2) @ (mu1 - mu2) + np.trace(s1) + np.trace(s2)
                 - 2.0 * np.sqrt(lam).real.sum())  # fmt: skip


def correlated(rng: np.random.Generator, n: int, d: int) -> np.ndarray:
    """Features with a spread of variances and correlations, like z-scored motion features."""
    mixing = rng.normal(size=(d, d)) * rng.uniform(0.1, 2.0, size=d)
    return rng.normal(size=(n, d)) @ mixing.T / np.sqrt(d)


@pytest.mark.parametrize(("n", "d"), [(12, 72), (20, 72), (8, 32), (90, 72), (200, 32)])
def test_the_bound_covers_the_exact_value_and_another_sqrtm(n: int, d: int) -> None:
    worst_ratio = 0.0
    for seed in range(5):
        rng = np.random.default_rng(1000 * n + seed)
        x, r = correlated(rng, n, d), correlated(rng, n + 3, d)
        result = frechet_distance(x, r, normalize=False)
        bound = result.details["sqrtm_error_bound"]
        for other in (exact_fd(x, r), eig_sqrtm_fd(x, r)):
            gap = abs(result.value - other)
            assert gap <= bound + 1e-12 * abs(other), (n, d, seed, gap, bound)
            worst_ratio = max(worst_ratio, gap / bound)
    print(f"n={n} d={d}: largest gap / bound {worst_ratio:.2g}")
    if n < d:  # singular: the bound is what limits agreement, and it is not vacuous
        assert 1e-9 < bound / abs(result.value) < 1e-3
    else:  # full rank: float64 rounding
        assert bound / abs(result.value) < 1e-8


def test_bound_is_zero_for_a_zero_product_and_nan_when_not_finite() -> None:
    assert sqrtm_error_bound(np.zeros((3, 3))) == 0.0
    assert np.isnan(sqrtm_error_bound(np.full((2, 2), np.inf)))
    # one zero eigenvalue of a 2x2 diagonal matrix: √(ε‖A‖) from it, ε‖A‖/(2√4) from the other
    eps = np.finfo(np.float64).eps
    a = np.diag([4.0, 0.0])
    assert sqrtm_error_bound(a) == pytest.approx(2 * (np.sqrt(4 * eps) + 4 * eps / 4))


def test_imag_over_tolerance_is_where_mint_raises() -> None:
    """Keys present on every result; True exactly when a diagonal imaginary part of sqrtm
    exceeds 1e-3 (mint: ValueError 'Imaginary component'), the value then taken from the real
    part."""
    mu = np.zeros(2)
    value, details = frechet_distance_from_moments(mu, np.eye(2), mu, np.diag([2.0, 0.5]))
    assert details["imag_over_tolerance"] is False and details["max_imag"] == 0.0
    assert details["imag_tolerance"] == IMAG_TOLERANCE == 1e-3
    assert value == pytest.approx(2 + 2.5 - 2 * (np.sqrt(2) + np.sqrt(0.5)))
    # A product with a negative eigenvalue (no covariance gives one): sqrtm is complex.
    sigma2 = np.diag([1.0, -0.01])
    covmean = linalg.sqrtm(np.eye(2) @ sigma2)
    assert np.max(np.abs(np.diagonal(covmean).imag)) > 1e-3  # mint would raise here
    value, details = frechet_distance_from_moments(mu, np.eye(2), mu, sigma2)
    assert details["imag_over_tolerance"] is True
    assert details["max_imag"] == pytest.approx(0.1)
    assert value == pytest.approx(2 + 0.99 - 2 * 1.0)  # Tr of the real part
