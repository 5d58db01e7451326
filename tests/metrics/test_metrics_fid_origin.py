"""The FID origin convention (docs/METRICS.md, "FID"): ``world`` (mint) vs ``first_frame_root``
(Bailando). Checked against the closed form of the reference's energy column, against a brute
force re-derivation of each placement, and on real AIST++ keypoints."""

from __future__ import annotations

import numpy as np
import pytest

from dancedata.compute.motion_features import kinetic_features
from dancedata.errors import InputError
from dancedata.metrics.fid import fid, motion_feature_matrix, with_origin
from dancedata.study.scoring import EvaluateParams


def _units(seed: int, n: int = 6, frames: int = 90, joints: int = 24) -> list[np.ndarray]:
    rng = np.random.default_rng(seed)
    out = []
    for _ in range(n):
        walk = np.cumsum(rng.normal(0, 0.01, (frames, joints, 3)), axis=0)
        out.append(walk + rng.normal(0, 0.5, (1, 1, 3)) + np.array([0.0, 1.0, 0.0]))
    return out


def test_energy_column_is_3540_times_the_distance_from_the_world_origin() -> None:
    """A joint at rest at p: the reference's v1 = p[k] − p[k−1]/dt makes its acceleration
    (fps − 1)·fps·p, so the energy column is 59·60·|p| = 3540·|p| at 60 fps."""
    p = np.array([[0.3, 1.2, -0.4], [1.5, 0.0, 2.0]])
    still = np.broadcast_to(p, (40, 2, 3))
    energy = kinetic_features(still, 60.0, mode="parity").reshape(2, 3)[:, 2]
    np.testing.assert_allclose(energy, 3540.0 * np.linalg.norm(p, axis=1), rtol=1e-12)
    corrected = kinetic_features(still, 60.0, mode="corrected").reshape(2, 3)[:, 2]
    np.testing.assert_allclose(corrected, 0.0, atol=1e-9)


def test_first_frame_root_is_the_unit_minus_its_first_root() -> None:
    unit = _units(0, n=1)[0]
    moved = with_origin(unit, "first_frame_root")
    np.testing.assert_array_equal(moved, unit - unit[0, 0])
    np.testing.assert_array_equal(moved[0, 0], 0.0)
    np.testing.assert_array_equal(with_origin(unit, "world"), unit)
    with pytest.raises(ValueError, match="origin must be one of world, first_frame_root"):
        with_origin(unit, "pelvis")  # type: ignore[arg-type]


def test_feature_matrix_under_each_origin_equals_brute_force() -> None:
    units = _units(1)
    world = motion_feature_matrix(units, "kinetic", origin="world")
    root = motion_feature_matrix(units, "kinetic", origin="first_frame_root")
    brute_world = np.stack([kinetic_features(u, 60.0, mode="parity") for u in units])
    brute_root = np.stack([kinetic_features(u - u[0, 0], 60.0, mode="parity") for u in units])
    np.testing.assert_array_equal(world, brute_world)
    np.testing.assert_array_equal(root, brute_root)
    assert not np.allclose(world, root)


def test_origin_moves_fid_k_and_not_fid_g_and_is_recorded() -> None:
    evaluated, reference = _units(2), _units(3)
    k_world = fid(evaluated, reference, "kinetic", origin="world")
    k_root = fid(evaluated, reference, "kinetic", origin="first_frame_root")
    g_world = fid(evaluated, reference, "geometric", origin="world")
    g_root = fid(evaluated, reference, "geometric", origin="first_frame_root")
    assert k_world.convention["origin"] == "world"
    assert k_root.convention["origin"] == "first_frame_root"
    assert abs(k_world.value - k_root.value) > 1e-3 * max(abs(k_world.value), 1.0)
    assert g_world.value == pytest.approx(g_root.value, rel=1e-9, abs=1e-9)


def test_first_frame_root_fid_k_ignores_where_each_unit_stands() -> None:
    """Shifting every unit by its own constant leaves first_frame_root FID_k unchanged; the
    world convention sees the shift through the energy column."""
    evaluated, reference = _units(4), _units(5)
    rng = np.random.default_rng(6)
    shifted = [u + rng.normal(0, 2.0, (1, 1, 3)) for u in evaluated]
    root = fid(evaluated, reference, "kinetic", origin="first_frame_root").value
    root_shifted = fid(shifted, reference, "kinetic", origin="first_frame_root").value
    world = fid(evaluated, reference, "kinetic", origin="world").value
    world_shifted = fid(shifted, reference, "kinetic", origin="world").value
    assert root_shifted == pytest.approx(root, rel=1e-5)  # sqrtm of a rank-deficient product
    assert abs(world_shifted - world) > 1e-2 * abs(world)


def test_evaluate_params_names_the_origin() -> None:
    assert EvaluateParams().fid_origin == "world"
    assert EvaluateParams(fid_origin="first_frame_root").as_dict()["fid_origin"] == (
        "first_frame_root"
    )
    with pytest.raises(InputError, match="fid_origin must be one of world, first_frame_root"):
        EvaluateParams(fid_origin="pelvis")


@pytest.mark.real_data
def test_origin_changes_kinetic_features_of_real_aist_keypoints(real_data) -> None:
    """Real AIST++ 3-d keypoints (COCO-17, metres): subtracting the first-frame root changes
    every energy column by 3540 × the shift, to float rounding, and leaves the kinetic energies
    alone."""
    from dancedata.io.aist_keypoints import read_keypoints3d

    files = sorted((real_data / "aist" / "keypoints3d").glob("*.pkl"))
    assert len(files) >= 2
    for file in files:
        kp = read_keypoints3d(file).keypoints3d_optim.astype(np.float64)[:600]
        world = kinetic_features(kp, 60.0, mode="parity").reshape(-1, 3)
        root = kinetic_features(with_origin(kp, "first_frame_root"), 60.0, mode="parity")
        root = root.reshape(-1, 3)
        np.testing.assert_allclose(world[:, :2], root[:, :2], rtol=1e-6, atol=1e-9)
        relative = np.abs(world[:, 2] - root[:, 2]) / world[:, 2]
        assert relative.max() > 0.1, relative
