"""Fréchet distance between two sets of feature vectors (docs/METRICS.md, FID), as mint computes it.

    FD = ‖μ1 − μ2‖² + Tr Σ1 + Tr Σ2 − 2 Tr (Σ1 Σ2)^{1/2}

Steps and their named parameters, in the order of mint ``tools/calculate_scores.py``
(``calculate_frechet_feature_distance`` → ``calculate_frechet_distance``, after pytorch-fid):

1. ``normalize`` (default on): z-score *both* sets by the reference set's mean and population
   std (ddof 0) plus ``std_eps`` = 1e−10. Only the reference's statistics are used.
   ``drop_constant_ref_columns`` (default off, the parity setting) removes the columns whose
   reference std is 0 first (they map to ±1e10·Δ otherwise); how many is reported.
2. Moments: ``moments="covariance"`` (mean and ``np.cov``, ddof 1; mint, Bailando) or
   ``"uncentred"`` (mean and XᵀX/N; Transflower's ``2moments``).
3. ``scipy.linalg.sqrtm(Σ1 Σ2)``; when the result is not finite, retried as
   ``sqrtm((Σ1 + εI)(Σ2 + εI))`` with ``eps`` (mint 1e−6; Bailando 1e−5; ``None`` = no retry,
   as Transflower). A complex result keeps its real part; the largest imaginary part dropped is
   reported (mint raises when a diagonal one exceeds 1e−3; here it is reported as
   ``details["imag_over_tolerance"]`` instead, so one bad matrix does not stop a run).

Precision (``details["sqrtm_error_bound"]``, :func:`sqrtm_error_bound`). With fewer units than
feature dimensions the covariances are singular, so Σ1 Σ2 has exactly-zero eigenvalues, where the
square root is not differentiable: a backward-stable sqrtm (SciPy's Schur method, in every
version) returns the root of Σ1 Σ2 + E with ‖E‖ ≈ ε‖Σ1 Σ2‖, and each zero eigenvalue, moved by up
to about ε‖Σ1 Σ2‖, contributes up to √(ε‖Σ1 Σ2‖) to the trace. SciPy versions differ in how
(SciPy 1.16 rewrote sqrtm), so the value is reproducible across versions only to within this
bound (about 3.6e−6 relative has been seen on 12 units of the 72 kinetic dims); with more units
than dimensions the bound is at float64 rounding.
"""

from __future__ import annotations

import warnings
from typing import Any, Literal

import numpy as np
from scipy import linalg

from dancedata.metrics.result import MetricResult

__all__ = [
    "IMAG_TOLERANCE",
    "frechet_distance",
    "frechet_distance_from_moments",
    "moments",
    "reference_normalization",
    "sqrtm_error_bound",
]

# mint's tolerance on the imaginary part of sqrtm's diagonal (np.allclose(..., atol=1e-3)).
IMAG_TOLERANCE = 1e-3

Moments = Literal["covariance", "uncentred"]


def _features(name: str, values: np.ndarray) -> np.ndarray:
    array = np.asarray(values, dtype=np.float64)
    if array.ndim != 2:
        raise ValueError(f"{name} must be (samples, dims), got {array.shape}")
    if not np.all(np.isfinite(array)):
        raise ValueError(f"{name} holds NaN or Inf")
    return array


def reference_normalization(
    reference: np.ndarray, std_eps: float = 1e-10
) -> tuple[np.ndarray, np.ndarray]:
    """(mean, std + std_eps) of the reference set, per column (std with ddof 0)."""
    ref = _features("reference features", reference)
    return ref.mean(axis=0), ref.std(axis=0) + std_eps


def moments(features: np.ndarray, kind: Moments = "covariance") -> tuple[np.ndarray, np.ndarray]:
    """(μ, Σ) of (n, d) features: ``np.cov`` (ddof 1) or the uncentred XᵀX / n."""
    x = _features("features", features)
    if kind == "covariance":
        if x.shape[0] < 2:
            raise ValueError("a covariance needs at least 2 samples")
        return x.mean(axis=0), np.atleast_2d(np.cov(x, rowvar=False))
    if kind == "uncentred":
        if x.shape[0] < 1:
            raise ValueError("moments of zero samples")
        return x.mean(axis=0), x.T @ x / x.shape[0]
    raise ValueError(f"moments must be 'covariance' or 'uncentred', got {kind!r}")


def sqrtm_error_bound(product: np.ndarray) -> float:
    """First-order bound on the error of ``2 Tr sqrtm(A)`` (A = Σ1 Σ2, as used) from float64
    rounding, i.e. how far two correct sqrtm implementations may disagree on the Fréchet
    distance.

    Tr sqrtm(A) = Σ √λᵢ depends on A's eigenvalues only. A backward-stable sqrtm returns the root
    of A + E with ‖E‖ ≤ δ = ε‖A‖_F (ε = float64 machine epsilon), which moves λᵢ by up to
    κᵢ δ, κᵢ = ‖yᵢ‖‖xᵢ‖ / |yᵢᴴxᵢ| its condition number (left and right eigenvectors; A = Σ1 Σ2
    is diagonalisable with real eigenvalues ≥ 0, but not normal, so κᵢ ≥ 1). Its root then moves
    by κᵢ δ / (2√λᵢ), or by up to √(κᵢ δ) when λᵢ ≤ κᵢ δ; eigenvalues at or below δ (the zero
    eigenvalues of a singular product, whose eigenvectors are not unique) count √δ. The bound is
    twice the sum over the eigenvalues (the distance has −2 Tr). Without κᵢ the bound was
    exceeded twofold on full-rank products of ill-conditioned covariances (200 units × 32 dims,
    cond Σ1 ≈ 1e7; tests/metrics/test_frechet_precision.py).
    """
    a = np.atleast_2d(np.asarray(product, dtype=np.float64))
    if a.size == 0 or not np.all(np.isfinite(a)):
        return float("nan")
    delta = np.finfo(np.float64).eps * float(np.linalg.norm(a))
    if delta == 0.0:
        return 0.0
    values, left, right = linalg.eig(a, left=True, right=True)
    magnitude = np.abs(values)
    overlap = np.abs(np.sum(left.conj() * right, axis=0))
    norms = np.linalg.norm(left, axis=0) * np.linalg.norm(right, axis=0)
    with np.errstate(divide="ignore", invalid="ignore"):
        kappa = np.where(overlap > 0.0, norms / overlap, np.inf)
    shift = np.where(magnitude > delta, np.maximum(kappa, 1.0) * delta, delta)
    per = np.where(magnitude > shift, shift / (2.0 * np.sqrt(np.maximum(magnitude, shift))),
                   np.sqrt(shift))  # fmt: skip
    return float(2.0 * per.sum())


def frechet_distance_from_moments(
    mu1: np.ndarray,
    sigma1: np.ndarray,
    mu2: np.ndarray,
    sigma2: np.ndarray,
    eps: float | None = 1e-6,
    imag_tolerance: float = IMAG_TOLERANCE,
) -> tuple[float, dict[str, Any]]:
    """The Fréchet distance of two Gaussians, and diagnostics.

    ``details``: ``eps_retry`` (sqrtm was not finite and was retried with ``eps`` I added);
    ``max_imag`` (the largest |imaginary part| of sqrtm's result, dropped; 0 for a real result);
    ``imag_over_tolerance``: True when an imaginary part on sqrtm's *diagonal* exceeds
    ``imag_tolerance`` (1e−3, mint's), i.e. where mint's code raises "Imaginary component";
    the value is then still Tr of the real part, but Σ1 Σ2 was too ill-conditioned for its
    root to be trusted, so read the number as unreliable; ``imag_tolerance`` itself;
    ``sqrtm_error_bound`` (:func:`sqrtm_error_bound`: how far the value may move between
    correct sqrtm implementations, e.g. SciPy versions); ``sqrtm_warning`` when SciPy warned.
    """
    mu1, mu2 = np.atleast_1d(mu1), np.atleast_1d(mu2)
    sigma1, sigma2 = np.atleast_2d(sigma1), np.atleast_2d(sigma2)
    if mu1.shape != mu2.shape or sigma1.shape != sigma2.shape:
        raise ValueError(
            f"moment shapes differ: {mu1.shape}/{sigma1.shape} vs {mu2.shape}/{sigma2.shape}"
        )
    details: dict[str, Any] = {"eps_retry": False}
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always", linalg.LinAlgWarning)
        product = sigma1 @ sigma2
        covmean = linalg.sqrtm(product)
        if not np.all(np.isfinite(covmean)) and eps is not None:
            offset = np.eye(sigma1.shape[0]) * eps
            product = (sigma1 + offset) @ (sigma2 + offset)
            covmean = linalg.sqrtm(product)
            details["eps_retry"] = True
    if caught:  # e.g. "Matrix is singular": reported with the value, not printed
        details["sqrtm_warning"] = str(caught[-1].message)[:200]
    # The same keys whether or not this SciPy returned a complex array (1.16+ often does not).
    details["max_imag"] = 0.0
    details["imag_over_tolerance"] = False
    details["imag_tolerance"] = imag_tolerance
    if np.iscomplexobj(covmean):
        details["max_imag"] = float(np.max(np.abs(covmean.imag)))
        details["imag_over_tolerance"] = bool(
            np.max(np.abs(np.diagonal(covmean).imag)) > imag_tolerance
        )
        covmean = covmean.real
    details["sqrtm_error_bound"] = sqrtm_error_bound(product)
    diff = mu1 - mu2
    value = float(diff @ diff + np.trace(sigma1) + np.trace(sigma2) - 2.0 * np.trace(covmean))
    return value, details


def frechet_distance(
    evaluated: np.ndarray,
    reference: np.ndarray,
    *,
    name: str = "frechet_distance",
    normalize: bool = True,
    std_eps: float = 1e-10,
    drop_constant_ref_columns: bool = False,
    moments_kind: Moments = "covariance",
    eps: float | None = 1e-6,
    n_frames: int = 0,
) -> MetricResult:
    """Fréchet distance between (n_eval, d) and (n_ref, d) feature sets (module docstring).

    Args:
        evaluated: features of the evaluated (generated / reconstructed) units.
        reference: features of the reference (ground-truth) units; the only set whose
            statistics normalise.
        name: the metric name to return (``fid_k``, ``fid_g``, ``fpd``...).
        normalize, std_eps, drop_constant_ref_columns, moments_kind, eps: the convention.
        n_frames: motion frames behind the evaluated features (recorded only).
    """
    x = _features("evaluated features", evaluated)
    r = _features("reference features", reference)
    if x.shape[1] != r.shape[1]:
        raise ValueError(f"feature widths differ: {x.shape[1]} vs {r.shape[1]}")
    keep = r.std(axis=0) > 0
    details: dict[str, Any] = {
        "n_reference": int(r.shape[0]),
        "constant_ref_columns": int((~keep).sum()),
    }
    if drop_constant_ref_columns:
        details["dropped_columns"] = int((~keep).sum())
        x, r = x[:, keep], r[:, keep]
    if normalize:
        mean, std = reference_normalization(r, std_eps)
        x, r = (x - mean) / std, (r - mean) / std
    mu1, s1 = moments(x, moments_kind)
    mu2, s2 = moments(r, moments_kind)
    value, fd_details = frechet_distance_from_moments(mu1, s1, mu2, s2, eps)
    convention = {
        "normalize": "reference_zscore" if normalize else "none",
        "std_eps": std_eps if normalize else None,
        "drop_constant_ref_columns": drop_constant_ref_columns,
        "moments": moments_kind,
        "eps": eps,
        "sqrtm": "scipy.linalg.sqrtm",
    }
    return MetricResult(
        name, value, convention, int(x.shape[0]), int(n_frames), {**details, **fd_details}
    )
