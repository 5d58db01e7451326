"""Root-flip repair: flips injected at known frames into real and synthetic root rotations are
found exactly, removed (the repaired orientation equals the original up to the motion of one
frame), and clean motion passes unchanged."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from dancedata.compute.hip_flips import repair_root_flips, root_step_angles
from dancedata.io.aist import read_motion


def _inject(root: np.ndarray, spans: list[tuple[int, int]], axis=(0.0, 1.0, 0.0)) -> np.ndarray:
    rot = Rotation.from_rotvec(root)
    half = Rotation.from_rotvec(np.pi * np.asarray(axis) / np.linalg.norm(axis))
    out = root.copy()
    for a, b in spans:
        out[a:b] = (half * rot[a:b]).as_rotvec()
    return out


def _angle_between(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    return np.degrees((Rotation.from_rotvec(a) * Rotation.from_rotvec(b).inv()).magnitude())


def _smooth_root(n: int = 300, fps: float = 30.0) -> np.ndarray:
    t = np.arange(n) / fps
    return np.stack([0.2 * np.sin(2 * t), 1.5 * t, 0.1 * np.cos(3 * t)], axis=1)


def test_clean_motion_is_unchanged():
    root = _smooth_root()
    fixed = repair_root_flips(root)
    assert fixed.frames.size == 0 and np.array_equal(fixed.root, root)
    assert "no root flips" in fixed.summary()


@pytest.mark.parametrize("axis", [(0, 1, 0), (0.3, 1, 0.1), (1, 0, 0)])
def test_injected_flips_are_found_and_removed(axis):
    root = _smooth_root()
    spans = [(40, 47), (120, 121), (200, 260)]
    flipped = _inject(root, spans, axis)
    fixed = repair_root_flips(flipped)
    # every flipped frame is turned back, and nothing else
    assert fixed.frames.tolist() == [*range(40, 47), 120, *range(200, 260)]
    assert fixed.runs == spans
    starts = np.isin(fixed.frames, [a for a, _ in spans])
    assert np.all(fixed.angles_deg[starts] > 170)
    step = root_step_angles(root).max()  # the real motion per frame, degrees
    assert _angle_between(fixed.root, root).max() < 2 * step + 1e-9
    assert root_step_angles(fixed.root).max() < 3 * step + 1e-9
    assert fixed.summary().startswith("3 root flip(s) above 90° per frame repaired, 68 frame(s)")


@pytest.mark.real_data
def test_on_real_aist_roots(real_data):
    for path in sorted((real_data / "aist" / "motions").glob("*.pkl"))[:3]:
        root = read_motion(path).axis_angle[:, 0].astype(np.float64)
        assert repair_root_flips(root).frames.size == 0, path.name  # real dance never flips
        flipped = _inject(root, [(100, 130), (400, 402)])
        fixed = repair_root_flips(flipped)
        assert fixed.runs == [(100, 130), (400, 402)], path.name
        step = root_step_angles(root).max()
        assert _angle_between(fixed.root, root).max() < 2 * step + 1e-6, path.name


def test_refuses_nonsense():
    with pytest.raises(ValueError, match="threshold"):
        repair_root_flips(np.zeros((3, 3)), threshold_deg=180)
    with pytest.raises(ValueError, match="finite"):
        repair_root_flips(np.full((3, 3), np.nan))
