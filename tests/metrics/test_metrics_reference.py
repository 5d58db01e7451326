"""Our metrics against independent transcriptions of the public code they follow
(docs/EXPERIMENTS.md §4.10), on the same inputs, within 1e-6 (Fréchet distances: plus the sqrtm
error bound their result records, which is at float64 rounding unless there are fewer units than
dimensions).

Each ``ref_*`` function below transcribes one public function (file and function named in its
docstring) into a plain loop, kept as close to the original as possible; it shares no code with
``dancedata.metrics``. Deviations forced by today's libraries are noted in place.
"""

from __future__ import annotations

import numpy as np
import pytest
import scipy.signal as scisignal
from scipy import linalg
from scipy.ndimage import gaussian_filter
from scipy.signal import argrelextrema

from dancedata.metrics import (
    bas_bailando,
    bas_mint,
    diversity,
    fid,
    fmd,
    fpd,
    frechet_distance,
    motion_feature_matrix,
)

# ------------------------------------------------------------------- transcribed references


def ref_mint_calculate_frechet_distance(mu1, sigma1, mu2, sigma2, eps=1e-6):
    """google-research/mint tools/calculate_scores.py ``calculate_frechet_distance`` (itself
    from pytorch-fid). ``linalg.sqrtm(..., disp=False)`` is written without ``disp`` (deprecated
    in SciPy 1.16, same matrix returned)."""
    mu1 = np.atleast_1d(mu1)
    mu2 = np.atleast_1d(mu2)
    sigma1 = np.atleast_2d(sigma1)
    sigma2 = np.atleast_2d(sigma2)
    assert mu1.shape == mu2.shape
    assert sigma1.shape == sigma2.shape
    diff = mu1 - mu2
    covmean = linalg.sqrtm(sigma1.dot(sigma2))
    if not np.isfinite(covmean).all():
        offset = np.eye(sigma1.shape[0]) * eps
        covmean = linalg.sqrtm((sigma1 + offset).dot(sigma2 + offset))
    if np.iscomplexobj(covmean):
        if not np.allclose(np.diagonal(covmean).imag, 0, atol=1e-3):
            m = np.max(np.abs(covmean.imag))
            raise ValueError(f"Imaginary component {m}")
        covmean = covmean.real
    tr_covmean = np.trace(covmean)
    return diff.dot(diff) + np.trace(sigma1) + np.trace(sigma2) - 2 * tr_covmean


def ref_mint_calculate_frechet_feature_distance(feature_list1, feature_list2):
    """mint tools/calculate_scores.py ``calculate_frechet_feature_distance``: list 1 is the real
    set (its statistics normalise both)."""
    feature_list1 = np.stack(feature_list1)
    feature_list2 = np.stack(feature_list2)
    mean = np.mean(feature_list1, axis=0)
    std = np.std(feature_list1, axis=0) + 1e-10
    feature_list1 = (feature_list1 - mean) / std
    feature_list2 = (feature_list2 - mean) / std
    return ref_mint_calculate_frechet_distance(
        mu1=np.mean(feature_list1, axis=0),
        sigma1=np.cov(feature_list1, rowvar=False),
        mu2=np.mean(feature_list2, axis=0),
        sigma2=np.cov(feature_list2, rowvar=False),
    )


def ref_mint_motion_peak_onehot(joints):
    """mint tools/calculate_beat_scores.py @ 83d64b9 ``motion_peak_onehot`` (float32 velocity
    as in the original)."""
    velocity = np.zeros_like(joints, dtype=np.float32)
    velocity[1:] = joints[1:] - joints[:-1]
    velocity_norms = np.linalg.norm(velocity, axis=2)
    envelope = np.sum(velocity_norms, axis=1)
    peak_idxs = scisignal.argrelextrema(envelope, np.less, axis=0, order=10)
    peak_onehot = np.zeros_like(envelope, dtype=bool)
    peak_onehot[peak_idxs] = 1
    return peak_onehot


def ref_mint_alignment_score(music_beats, motion_beats, sigma=3):
    """mint tools/calculate_beat_scores.py @ 83d64b9 ``alignment_score``."""
    if motion_beats.sum() == 0:
        return 0.0
    music_beat_idxs = np.where(music_beats)[0]
    motion_beat_idxs = np.where(motion_beats)[0]
    score_all = []
    for motion_beat_idx in motion_beat_idxs:
        dists = np.abs(music_beat_idxs - motion_beat_idx).astype(np.float32)
        ind = np.argmin(dists)
        score = np.exp(-(dists[ind] ** 2) / 2 / sigma**2)
        score_all.append(score)
    return sum(score_all) / len(score_all)


def ref_bailando_calc_db(keypoints):
    """lisiyao21/Bailando utils/beat_align_score.py ``calc_db``."""
    keypoints = np.array(keypoints).reshape(-1, 24, 3)
    kinetic_vel = np.mean(np.sqrt(np.sum((keypoints[1:] - keypoints[:-1]) ** 2, axis=2)), axis=1)
    kinetic_vel = gaussian_filter(kinetic_vel, 5)
    motion_beats = argrelextrema(kinetic_vel, np.less)
    return motion_beats, len(kinetic_vel)


def ref_bailando_get_mb_from_onehot(beats_onehot, length):
    """Bailando utils/beat_align_score.py ``get_mb`` minus the JSON reading: column 53 of its
    music features is the beat one-hot; truncated to ``length``."""
    beats = np.array(beats_onehot)[:length].astype(bool)
    beat_axis = np.arange(len(beats))
    return beat_axis[beats]


def ref_bailando_ba(music_beats, motion_beats):
    """Bailando utils/beat_align_score.py ``BA``."""
    ba = 0
    for bb in music_beats:
        ba += np.exp(-np.min((motion_beats[0] - bb) ** 2) / 2 / 9)
    return ba / len(music_beats)


def ref_bailando_normalize(feat, feat2):
    """Bailando utils/metrics_new.py ``normalize`` (feat = ground truth)."""
    mean = feat.mean(axis=0)
    std = feat.std(axis=0)
    return (feat - mean) / (std + 1e-10), (feat2 - mean) / (std + 1e-10)


def ref_bailando_calc_fid(kps_gen, kps_gt):
    """Bailando utils/metrics_new.py ``calc_fid`` (eps 1e-5; a complex square root whose
    diagonal imaginary part is small stays complex there: the real part is taken at the end,
    which is what printing it as a float shows)."""
    mu_gen = np.mean(kps_gen, axis=0)
    sigma_gen = np.cov(kps_gen, rowvar=False)
    mu_gt = np.mean(kps_gt, axis=0)
    sigma_gt = np.cov(kps_gt, rowvar=False)
    mu1, mu2, sigma1, sigma2 = mu_gen, mu_gt, sigma_gen, sigma_gt
    diff = mu1 - mu2
    eps = 1e-5
    covmean = linalg.sqrtm(sigma1.dot(sigma2))
    if not np.isfinite(covmean).all():
        offset = np.eye(sigma1.shape[0]) * eps
        covmean = linalg.sqrtm((sigma1 + offset).dot(sigma2 + offset))
    if np.iscomplexobj(covmean):  # noqa: SIM102 (kept as written there)
        if not np.allclose(np.diagonal(covmean).imag, 0, atol=1e-3):
            covmean = covmean.real
    tr_covmean = np.trace(covmean)
    return np.real(diff.dot(diff) + np.trace(sigma1) + np.trace(sigma2) - 2 * tr_covmean)


def ref_bailando_calculate_avg_distance(feature_list):
    """Bailando utils/metrics_new.py ``calculate_avg_distance`` (features already normalised)."""
    feature_list = np.stack(feature_list)
    n = feature_list.shape[0]
    dist = 0
    for i in range(n):
        for j in range(i + 1, n):
            dist += np.linalg.norm(feature_list[i] - feature_list[j])
    dist /= (n * n - n) / 2
    return dist


def ref_transflower_moments(features, stat):
    """guillefix/transflower-lightning feature_extraction/extract_transform.py, transforms
    ``2moments`` and ``2moments_ext`` (features = all files' frames concatenated)."""
    if stat == "2moments":
        C = np.dot(features.T, features) / features.shape[0]  # noqa: N806 (their name)
        m = np.mean(features, 0)
        return m, C
    if features.shape[0] % 3 != 0:
        features = features[: -(features.shape[0] % 3)]
    features = np.reshape(features, (-1, 3 * features.shape[1]))
    C = np.dot(features.T, features) / features.shape[0]  # noqa: N806
    m = np.mean(features, 0)
    return m, C


def ref_transflower_fid(m, C, mg, Cg):  # noqa: N803 (their names)
    """transflower-lightning analysis/sandbox_fid.py ``FID`` (its result can be complex when
    sqrtm is; the real part is compared)."""
    mean_diff = np.sum((m - mg) ** 2)
    covar_diff = np.trace(C) + np.trace(Cg) - 2 * np.trace(linalg.sqrtm(np.dot(C, Cg)))
    return np.real(mean_diff + covar_diff)


# ---------------------------------------------------------------------------------- inputs


def dance(rng: np.random.Generator, n_frames: int = 360) -> np.ndarray:
    """(F, 24, 3) joint positions (m) with a pulse: joints sway with a period of 25–40 frames
    plus noise, so the speed has clear minima (motion beats) like dance does."""
    t = np.arange(n_frames)[:, None, None]
    period = rng.uniform(25, 40)
    amp = rng.uniform(0.02, 0.2, size=(1, 24, 3))
    phase = rng.uniform(0, 2 * np.pi, size=(1, 24, 3))
    base = rng.normal(scale=0.4, size=(1, 24, 3))
    wander = np.cumsum(rng.normal(scale=0.003, size=(n_frames, 1, 3)), axis=0)
    sway = amp * np.sin(2 * np.pi * t / period + phase)
    return base + sway + wander + rng.normal(scale=0.002, size=(n_frames, 24, 3))


def music_onehot(rng: np.random.Generator, n_frames: int) -> np.ndarray:
    """A per-frame beat one-hot: a beat every 28–36 frames with ±2 frames of jitter."""
    step = rng.integers(28, 37)
    beats = np.arange(rng.integers(0, step), n_frames + 40, step)
    beats = np.clip(beats + rng.integers(-2, 3, size=beats.size), 0, None)
    onehot = np.zeros(n_frames + 40, dtype=np.float32)  # audio runs past the motion
    onehot[beats] = 1.0
    return onehot


SEEDS = range(20)


def fd_tolerance(reference: float, ours) -> float:
    """1e-6 relative, plus twice the sqrtm error bound of our result: with fewer units than
    dimensions each side's Tr sqrtm may be off the exact value by that bound, and by a
    different amount on another SciPy (dancedata.metrics.frechet)."""
    return 1e-6 * max(1.0, abs(reference)) + 2.0 * ours.details["sqrtm_error_bound"]


# ------------------------------------------------------------------------------------ tests


def test_beat_scores_match_mint_and_bailando_code() -> None:
    mint_diffs, bailando_diffs = [], []
    for seed in SEEDS:
        rng = np.random.default_rng(seed)
        joints = dance(rng)
        onehot = music_onehot(rng, joints.shape[0])
        beats = np.flatnonzero(onehot)

        # mint: real-data path, audio beats cut to the motion's length
        ref = ref_mint_alignment_score(
            onehot[: joints.shape[0]], ref_mint_motion_peak_onehot(joints), sigma=3
        )
        ours = bas_mint(joints, beats)
        mint_diffs.append(abs(ours - ref))

        motion_beats, length = ref_bailando_calc_db(joints)
        ref_b = ref_bailando_ba(ref_bailando_get_mb_from_onehot(onehot, length), motion_beats)
        bailando_diffs.append(abs(bas_bailando(joints, beats) - ref_b))
    assert max(mint_diffs) < 1e-6, max(mint_diffs)
    assert max(bailando_diffs) < 1e-6, max(bailando_diffs)


def test_the_two_beat_scores_really_differ() -> None:
    """Named separately for a reason: on the same inputs they give different numbers."""
    rng = np.random.default_rng(100)
    joints = dance(rng)
    beats = np.flatnonzero(music_onehot(rng, joints.shape[0]))
    assert abs(bas_mint(joints, beats) - bas_bailando(joints, beats)) > 1e-3


@pytest.mark.parametrize("n_units", [12, 90])  # fewer and more units than the 72 kinetic dims
def test_fid_matches_mint_and_bailando_code(n_units: int) -> None:
    rng = np.random.default_rng(n_units)
    real = [dance(rng, 240) for _ in range(n_units)]
    gen = [p + rng.normal(scale=0.01, size=p.shape) * rng.uniform(0.5, 2) for p in real]
    for kind in ("kinetic", "geometric"):
        f_real = motion_feature_matrix(real, kind)
        f_gen = motion_feature_matrix(gen, kind)
        keep = f_real.std(axis=0) > 0  # constant reference columns explode under z-scoring
        f_real, f_gen = f_real[:, keep], f_gen[:, keep]

        result = frechet_distance(f_gen, f_real)
        ours = result.value
        mint = ref_mint_calculate_frechet_feature_distance(list(f_real), list(f_gen))
        assert abs(ours - mint) < fd_tolerance(mint, result), (kind, ours, mint)

        gt_n, gen_n = ref_bailando_normalize(f_real, f_gen)
        bailando = ref_bailando_calc_fid(gen_n, gt_n)
        result_b = frechet_distance(f_gen, f_real, eps=1e-5)
        ours_b = result_b.value
        assert abs(ours_b - bailando) < fd_tolerance(bailando, result_b), (kind, ours_b, bailando)

        div = diversity(f_gen, f_real).value
        assert abs(div - ref_bailando_calculate_avg_distance(gen_n)) < 1e-6
        div_gt = diversity(f_real, f_real).value
        assert abs(div_gt - ref_bailando_calculate_avg_distance(gt_n)) < 1e-6

    # the full path (features + distance) as mint runs it, kinetic features
    full_result = fid(gen, real, "kinetic")
    full = full_result.value
    mint_full = ref_mint_calculate_frechet_feature_distance(
        list(motion_feature_matrix(real, "kinetic")), list(motion_feature_matrix(gen, "kinetic"))
    )
    assert abs(full - mint_full) < fd_tolerance(mint_full, full_result)


def test_fpd_fmd_transflower_parity_matches_transflower_code() -> None:
    rng = np.random.default_rng(7)
    real = [rng.normal(scale=0.4, size=(n, 6, 3)) for n in (301, 250, 199)]
    gen = [r[: len(r) - 7] * 1.2 + 0.05 for r in real]
    pooled_real = np.concatenate([r.reshape(len(r), -1) for r in real])
    pooled_gen = np.concatenate([g.reshape(len(g), -1) for g in gen])
    for stat, ours in (("2moments", fpd), ("2moments_ext", fmd)):
        ref = ref_transflower_fid(
            *ref_transflower_moments(pooled_gen, stat), *ref_transflower_moments(pooled_real, stat)
        )
        value = ours(gen, real, frame_step=1, parity="transflower").value
        assert abs(value - ref) < 1e-6 * max(1.0, abs(ref)), (stat, value, ref)
