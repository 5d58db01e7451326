"""dancedata.compute.camera, the one module of camera math: look-at placement, pinhole
projection (against OpenCV and the closed form P = K [R | t]) and the orthographic view cameras
of the skeleton videos (against hand-computed pixels)."""

from __future__ import annotations

import cv2
import numpy as np
import pytest

from dancedata.compute.camera import (
    fit_view_camera,
    look_at,
    project_orthographic,
    project_points,
    projection_matrix,
    rodrigues_to_rotmat,
    screen_axes,
)
from dancedata.errors import InputError


def test_look_at_closed_form_for_a_camera_on_the_z_axis() -> None:
    # At (0, 0, 5) looking at the origin: forward −z, right +x, image down −y (world y is up).
    rot = look_at(np.array([0.0, 0.0, 5.0]), np.zeros(3))
    np.testing.assert_allclose(rot, [[1, 0, 0], [0, -1, 0], [0, 0, -1]], atol=1e-15)


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_look_at_puts_the_target_on_the_principal_point_through_opencv(seed: int) -> None:
    rng = np.random.default_rng(seed)
    centre = rng.uniform(-500, 500, 3) + np.array([0.0, 150.0, 0.0])
    target = rng.uniform(-50, 50, 3)
    rot = look_at(centre, target)
    np.testing.assert_allclose(rot @ rot.T, np.eye(3), atol=1e-12)
    assert np.linalg.det(rot) == pytest.approx(1.0)
    k = np.array([[1400.0, 0, 960], [0, 1400.0, 540], [0, 0, 1]])
    rvec = cv2.Rodrigues(rot)[0].ravel()
    tvec = -rot @ centre
    above = target + np.array([0.0, 10.0, 0.0])  # a point above the target: higher in the image
    pixels, _ = cv2.projectPoints(np.stack([target, above]), rvec, tvec, k, np.zeros(5))
    np.testing.assert_allclose(pixels[0, 0], [960, 540], atol=1e-6)
    assert pixels[1, 0, 1] < 540
    mine = project_points(
        np.stack([target, above]), k[None], rvec[None], tvec[None], np.zeros((1, 5))
    )
    np.testing.assert_allclose(mine[0], pixels[:, 0], atol=1e-6)


def test_rodrigues_of_zero_and_of_a_quarter_turn() -> None:
    np.testing.assert_allclose(rodrigues_to_rotmat(np.zeros(3)), np.eye(3))
    quarter = rodrigues_to_rotmat(np.array([0.0, 0.0, np.pi / 2]))
    np.testing.assert_allclose(quarter, [[0, -1, 0], [1, 0, 0], [0, 0, 1]], atol=1e-15)
    np.testing.assert_allclose(quarter, cv2.Rodrigues(np.array([0.0, 0.0, np.pi / 2]))[0])


def test_projection_matrix_agrees_with_undistorted_projection() -> None:
    rng = np.random.default_rng(3)
    n = 4
    k = np.tile(np.array([[1500.0, 0.5, 960], [0, 1480.0, 540], [0, 0, 1]]), (n, 1, 1))
    rvec = rng.uniform(-0.3, 0.3, (n, 3))
    tvec = np.column_stack([rng.uniform(-0.2, 0.2, (n, 2)), rng.uniform(4, 6, n)])
    points = rng.uniform(-1, 1, (7, 3))
    p = projection_matrix(k, rodrigues_to_rotmat(rvec), tvec)  # (n, 3, 4)
    homogeneous = np.einsum("cij,nj->cni", p, np.column_stack([points, np.ones(7)]))
    expected = homogeneous[..., :2] / homogeneous[..., 2:]
    np.testing.assert_allclose(project_points(points, k, rvec, tvec, np.zeros((n, 5))), expected)


def test_screen_axes_closed_forms() -> None:
    np.testing.assert_array_equal(screen_axes("y", "front"), [[1, 0, 0], [0, 1, 0]])
    np.testing.assert_array_equal(screen_axes("z", "front"), [[1, 0, 0], [0, 0, 1]])
    np.testing.assert_array_equal(screen_axes("y", "side"), [[0, 0, -1], [0, 1, 0]])
    np.testing.assert_array_equal(screen_axes("y", "top"), [[1, 0, 0], [0, 0, -1]])
    np.testing.assert_array_equal(screen_axes("-y", "front"), [[1, 0, 0], [0, -1, 0]])
    with pytest.raises(InputError, match="up axis"):
        screen_axes("w", "front")
    with pytest.raises(InputError, match="view must be"):
        screen_axes("y", "back")


def test_fitted_orthographic_camera_maps_the_bounding_box_by_hand() -> None:
    # y-up joints spanning x 0..2 m, y 0..1 m; a 100×100 px area at (10, 20) with 10 % margin:
    # usable 80×80 px, scale min(80/2, 80/1) = 40 px/m, box centre (1, 0.5) at pixel (60, 70).
    points = np.array([[[0.0, 0.0, 0.3], [2.0, 1.0, -0.4]], [[1.0, 0.5, 0.0], [np.nan] * 3]])
    camera = fit_view_camera(points, "world", "y", "front", (10, 20, 100, 100), margin=0.1)
    assert camera.scale == pytest.approx(40.0)
    pixels = project_orthographic(camera, points)
    np.testing.assert_allclose(pixels[0], [[20.0, 90.0], [100.0, 50.0]])  # y grows downward
    np.testing.assert_allclose(pixels[1, 0], [60.0, 70.0])
    assert np.isnan(pixels[1, 1]).all()


def test_image_poses_keep_their_y_direction_and_have_only_a_front_view() -> None:
    points = np.array([[[100.0, 50.0], [300.0, 250.0]]])  # source-video pixels, y down
    camera = fit_view_camera(points, "image", "y", "front", (0, 0, 200, 200), margin=0.0)
    np.testing.assert_allclose(project_orthographic(camera, points)[0], [[0, 0], [200, 200]])
    with pytest.raises(InputError, match="only the camera's own view"):
        fit_view_camera(points, "image", "y", "side", (0, 0, 200, 200))
    with pytest.raises(InputError, match="no finite joint"):
        fit_view_camera(np.full((2, 3, 3), np.nan), "world", "y", "front", (0, 0, 10, 10))
