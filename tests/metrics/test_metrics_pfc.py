"""PFC (EDGE's Physical Foot Contact score) against EDGE's ``eval/eval_pfc.py`` re-derived here
step by step (root velocity then acceleration over DT = 1/30, z up, joints 7, 10, 8, 11), on
synthetic clips and on real AIST++ 3-d keypoints."""

from __future__ import annotations

import math

import numpy as np
import pytest

from dancedata.metrics.pfc import pfc, pfc_clip, pfc_clips


def edge_pfc(clips: list[np.ndarray]) -> float:
    """EDGE ``calc_physical_score`` on in-memory clips (z up, 30 fps), written from its code."""
    scores = []
    up_dir = 2
    flat_dirs = [i for i in range(3) if i != up_dir]
    dt = 1 / 30
    for joint3d in clips:
        root_v = (joint3d[1:, 0, :] - joint3d[:-1, 0, :]) / dt
        root_a = (root_v[1:] - root_v[:-1]) / dt
        root_a[:, up_dir] = np.maximum(root_a[:, up_dir], 0)
        root_a = np.linalg.norm(root_a, axis=-1)
        root_a /= root_a.max()
        feet = joint3d[:, [7, 10, 8, 11]]
        foot_v = np.linalg.norm(feet[2:, :, flat_dirs] - feet[1:-1, :, flat_dirs], axis=-1)
        foot_mins = np.zeros((len(foot_v), 2))
        foot_mins[:, 0] = np.minimum(foot_v[:, 0], foot_v[:, 1])
        foot_mins[:, 1] = np.minimum(foot_v[:, 2], foot_v[:, 3])
        scores.append((foot_mins[:, 0] * foot_mins[:, 1] * root_a).mean())
    return float(np.mean(scores) * 10000)


def _dance(seed: int, frames: int = 150) -> np.ndarray:
    """A z-up clip: a wandering, bobbing root and 23 joints jittering around it."""
    rng = np.random.default_rng(seed)
    t = np.arange(frames) / 30.0
    root = np.stack(
        [0.3 * np.sin(1.3 * t + seed), 0.2 * np.cos(0.7 * t), 0.9 + 0.05 * np.sin(6.0 * t)], 1
    )
    joints = root[:, None, :] + rng.normal(0, 0.3, (1, 24, 3))
    joints = joints + np.cumsum(rng.normal(0, 0.004, (frames, 24, 3)), axis=0)
    joints[:, 0] = root
    return joints


def _z_to_y(p: np.ndarray) -> np.ndarray:
    """z up → y up, a proper rotation: (x, y, z) → (x, z, −y)."""
    return np.stack([p[..., 0], p[..., 2], -p[..., 1]], axis=-1)


def test_pfc_equals_edge_on_synthetic_clips() -> None:
    clips = [_dance(s) for s in range(8)]
    ours = pfc(clips, fps=30.0, up_axis="z")
    assert ours.value == pytest.approx(edge_pfc([c.copy() for c in clips]), rel=1e-12)
    assert ours.value > 0
    assert ours.n_units == 8 and ours.n_frames == 8 * 150
    assert ours.convention["fps"] == 30.0 and ours.convention["clip_frames"] is None
    assert ours.convention["foot_joints"] == [7, 10, 8, 11]


def test_pfc_is_the_same_in_a_y_up_frame() -> None:
    clips = [_dance(s) for s in range(4)]
    z = pfc(clips, fps=30.0, up_axis="z").value
    y = pfc([_z_to_y(c) for c in clips], fps=30.0, up_axis="y").value
    assert y == pytest.approx(z, rel=1e-12)


def test_upward_root_push_counts_and_falling_does_not() -> None:
    """The clamp: a root falling freely (negative up acceleration only) scores 0 acceleration
    in the up direction, so with a horizontal wobble the score is what the wobble gives."""
    clip = _dance(3, 60)
    t = np.arange(60) / 30.0
    clip[:, 0, 2] = 2.0 - 4.9 * t**2  # free fall: a_z = −9.8 everywhere
    clip[:, 0, 0] = 0.01 * np.sin(5 * t)
    value = pfc_clip(clip, 30.0, "z")
    clipped = clip.copy()
    clipped[:, 0, 2] = 2.0  # no vertical motion at all
    assert value == pytest.approx(pfc_clip(clipped, 30.0, "z"), rel=1e-9)
    assert value == pytest.approx(edge_pfc([clip.copy()]) / 1e4, rel=1e-12)


def test_still_feet_score_zero_and_still_root_is_undefined() -> None:
    clip = _dance(1)
    clip[:, 7] = clip[0, 7]  # left ankle planted
    assert pfc_clip(clip, 30.0) == 0.0
    still = np.broadcast_to(_dance(2)[:1], (40, 24, 3)).copy()
    assert math.isnan(pfc_clip(still, 30.0))
    result = pfc([still, _dance(2)], fps=30.0)
    assert result.details["n_undefined"] == 1 and result.n_units == 1
    assert result.value == pytest.approx(edge_pfc([_dance(2)]), rel=1e-12)


def test_clips_cut_consecutively_and_change_the_value() -> None:
    seq = _dance(5, 320)
    parts = pfc_clips([seq], 150)
    assert [len(c) for _, c in parts] == [150, 150]
    np.testing.assert_array_equal(parts[1][1], seq[150:300])
    cut = pfc([seq], fps=30.0, clip_frames=150)
    assert cut.value == pytest.approx(edge_pfc([seq[:150].copy(), seq[150:300].copy()]), rel=1e-12)
    assert cut.convention["clip_frames"] == 150
    assert cut.value != pytest.approx(pfc([seq], fps=30.0).value, rel=1e-3)


def test_frame_rate_changes_the_value() -> None:
    """The same motion sampled at 60 fps: per-frame foot displacements halve, the value falls
    by about 4 (both factors): the recorded fps matters."""
    t60 = _dance(7, 300)
    at30 = pfc([t60[::2]], fps=30.0).value
    at60 = pfc([t60], fps=60.0).value
    assert at30 > 2.0 * at60


def test_bad_shapes_are_refused() -> None:
    with pytest.raises(ValueError, match="SMPL joint positions"):
        pfc_clip(np.zeros((10, 5, 3)), 30.0)
    with pytest.raises(ValueError, match="at least 3 frames"):
        pfc_clips([np.zeros((10, 24, 3))], 2)


@pytest.mark.real_data
def test_pfc_equals_edge_on_real_aist_keypoints(real_data) -> None:
    """Real AIST++ 3-d keypoints (COCO-17, metres, y up) in SMPL-24 slots: root = mid-hip, the
    ankles as feet (COCO has no toes), every other slot the nose; at 30 fps (every second
    frame), in EDGE's z-up frame, 5-second clips."""
    from dancedata.io.aist_keypoints import read_keypoints3d

    files = sorted((real_data / "aist" / "keypoints3d").glob("*.pkl"))
    assert files
    sequences_y, sequences_z = [], []
    for file in files:
        kp = read_keypoints3d(file).keypoints3d_optim.astype(np.float64)[::2]
        smpl = np.repeat(kp[:, :1], 24, axis=1)
        smpl[:, 0] = 0.5 * (kp[:, 11] + kp[:, 12])
        smpl[:, 7] = smpl[:, 10] = kp[:, 15]
        smpl[:, 8] = smpl[:, 11] = kp[:, 16]
        sequences_y.append(smpl)
        sequences_z.append(np.stack([smpl[..., 0], -smpl[..., 2], smpl[..., 1]], axis=-1))
    clips = [c for _, c in pfc_clips(sequences_z, 150)]
    assert len(clips) >= 4
    ours_z = pfc(sequences_z, fps=30.0, up_axis="z", clip_frames=150)
    ours_y = pfc(sequences_y, fps=30.0, up_axis="y", clip_frames=150)
    reference = edge_pfc([c.copy() for c in clips])
    assert ours_z.value == pytest.approx(reference, rel=1e-12)
    assert ours_y.value == pytest.approx(reference, rel=1e-9)
    assert 0 < reference < 1e3
