"""rot6d (Zhou's columns) and rot6d_rows (pytorch3d's / EDGE's rows), issue 14 item 6 bullet 1.

References transcribed here, independently of dancedata:
- pytorch3d.transforms.matrix_to_rotation_6d:
  ``batch_dim = matrix.size()[:-2]; return matrix[..., :2, :].clone().reshape(batch_dim + (6,))``
- pytorch3d.transforms.rotation_6d_to_matrix:
  ``a1, a2 = d6[..., :3], d6[..., 3:]; b1 = F.normalize(a1, dim=-1);
  b2 = a2 - (b1 * a2).sum(-1, keepdim=True) * b1; b2 = F.normalize(b2, dim=-1);
  b3 = torch.cross(b1, b2, dim=-1); return torch.stack((b1, b2, b3), dim=-2)``
- Zhou et al. 2019 (CVPR), eq. (15)/(16): the 6D vector is the first two columns of R and
  Gram–Schmidt of those columns rebuilds R column by column.
"""

from __future__ import annotations

import json

import numpy as np
import pytest
import zarr
from scipy.spatial.transform import Rotation

from dancedata.compute.motion_representations import representations_from_axis_angle
from dancedata.compute.rotations import (
    rot6d_rows_to_rotmat,
    rot6d_to_rotmat,
    rotmat_to_rot6d,
    rotmat_to_rot6d_rows,
)
from tests.helpers import run_cli


def pytorch3d_matrix_to_rotation_6d(matrix: np.ndarray) -> np.ndarray:
    batch_dim = matrix.shape[:-2]
    return matrix[..., :2, :].copy().reshape(batch_dim + (6,))


def pytorch3d_rotation_6d_to_matrix(d6: np.ndarray) -> np.ndarray:
    a1, a2 = d6[..., :3], d6[..., 3:]
    b1 = a1 / np.linalg.norm(a1, axis=-1, keepdims=True)
    b2 = a2 - (b1 * a2).sum(-1, keepdims=True) * b1
    b2 = b2 / np.linalg.norm(b2, axis=-1, keepdims=True)
    b3 = np.cross(b1, b2, axis=-1)
    return np.stack((b1, b2, b3), axis=-2)


def zhou_columns(matrix: np.ndarray) -> np.ndarray:
    return np.concatenate([matrix[..., :, 0], matrix[..., :, 1]], axis=-1)


@pytest.fixture(scope="module")
def rotations() -> np.ndarray:
    return Rotation.random(500, random_state=14).as_matrix().reshape(50, 10, 3, 3)


def test_rows_match_pytorch3d_and_columns_match_zhou(rotations):
    np.testing.assert_array_equal(
        rotmat_to_rot6d_rows(rotations), pytorch3d_matrix_to_rotation_6d(rotations)
    )
    np.testing.assert_array_equal(rotmat_to_rot6d(rotations), zhou_columns(rotations))
    # The layouts differ: rows of R are the columns of R transposed.
    np.testing.assert_array_equal(
        rotmat_to_rot6d_rows(rotations), rotmat_to_rot6d(np.swapaxes(rotations, -1, -2))
    )
    assert not np.allclose(rotmat_to_rot6d_rows(rotations), rotmat_to_rot6d(rotations))


def test_round_trips_through_gram_schmidt(rotations):
    rows = rotmat_to_rot6d_rows(rotations)
    np.testing.assert_allclose(rot6d_rows_to_rotmat(rows), rotations, atol=1e-12)
    np.testing.assert_allclose(pytorch3d_rotation_6d_to_matrix(rows), rotations, atol=1e-12)
    np.testing.assert_allclose(rot6d_to_rotmat(rotmat_to_rot6d(rotations)), rotations, atol=1e-12)
    # Off the manifold (a network's output): both decoders still agree with pytorch3d's.
    noisy = rows + np.random.default_rng(0).normal(scale=0.2, size=rows.shape)
    decoded = rot6d_rows_to_rotmat(noisy)
    np.testing.assert_allclose(decoded, pytorch3d_rotation_6d_to_matrix(noisy), atol=1e-12)
    np.testing.assert_allclose(
        decoded @ np.swapaxes(decoded, -1, -2), np.eye(3) + 0 * decoded, atol=1e-12
    )
    np.testing.assert_allclose(np.linalg.det(decoded), 1.0, atol=1e-12)


def test_the_wrong_decoder_inverts_the_rotation(rotations):
    """The issue's warning, shown: Zhou columns fed to pytorch3d's decoder give Rᵀ = R⁻¹."""
    wrong = pytorch3d_rotation_6d_to_matrix(rotmat_to_rot6d(rotations))
    np.testing.assert_allclose(wrong, np.swapaxes(rotations, -1, -2), atol=1e-12)


def test_representations_from_axis_angle_offers_both():
    aa = Rotation.random(40, random_state=3).as_rotvec().reshape(8, 5, 3)
    reps = representations_from_axis_angle(aa, ["rotmat", "rot6d", "rot6d_rows"], "XYZ")
    np.testing.assert_array_equal(
        reps["rot6d_rows"], pytorch3d_matrix_to_rotation_6d(reps["rotmat"])
    )
    np.testing.assert_array_equal(reps["rot6d"], zhou_columns(reps["rotmat"]))


@pytest.mark.slow
def test_featurize_writes_rot6d_rows_with_its_layout(tmp_path):
    raw, store = tmp_path / "raw", tmp_path / "store"
    run_cli("synth", "aist", str(raw), "--sequences", "1", "-q")
    run_cli("ingest", "aist", str(raw), "--store", str(store), "-q")
    out = run_cli(
        "featurize",
        str(store),
        "--no-audio",
        "--representations",
        "rotmat,rot6d,rot6d_rows",
        "--json",
    )
    version = json.loads(out.stdout)["version"]
    root = zarr.open_group(str(store / "versions" / version / "data.zarr"), mode="r")
    rotmat = np.asarray(root["motion/rotmat"][:])
    rows = root["motion/rot6d_rows"]
    assert rows.attrs["rot6d_layout"].startswith("pytorch3d-rows")
    assert root["motion/rot6d"].attrs["rot6d_layout"].startswith("zhou2019-columns")
    np.testing.assert_array_equal(np.asarray(rows[:]), pytorch3d_matrix_to_rotation_6d(rotmat))
    run_cli("validate", str(store))
    bad = run_cli("featurize", str(store), "--representations", "rot6d_cols", check=False)
    assert bad.returncode == 1 and "rot6d_rows" in bad.stderr
