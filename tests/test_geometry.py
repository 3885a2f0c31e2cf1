import numpy as np
import pytest

from scene3D.geometry import (
    angle_between_deg,
    as_points2d,
    distinct_correspondences,
    normalize_points,
    project,
    relative_pose,
    rotation_about_axis,
    rotation_angle_deg,
    rotation_error_deg,
    skew,
)


def test_skew_is_the_cross_product():
    a, b = np.array([0.3, -1.2, 2.0]), np.array([1.5, 0.2, -0.7])
    np.testing.assert_allclose(skew(a) @ b, np.cross(a, b))


def test_rotation_about_axis_is_proper_and_has_the_angle():
    R = rotation_about_axis([1.0, 2.0, -0.5], 33.0)
    np.testing.assert_allclose(R @ R.T, np.eye(3), atol=1e-12)
    assert np.linalg.det(R) == pytest.approx(1.0)
    assert rotation_angle_deg(R) == pytest.approx(33.0)
    assert rotation_error_deg(R, R) == pytest.approx(0.0, abs=1e-6)


def test_angle_between_depends_on_sign():
    assert angle_between_deg([1, 0, 0], [0, 1, 0]) == pytest.approx(90.0)
    assert angle_between_deg([1, 0, 0], [-2, 0, 0]) == pytest.approx(180.0)


def test_project_and_normalize_are_inverse():
    K = np.array([[800.0, 0, 330], [0, 780, 250], [0, 0, 1]])
    X = np.array([[0.5, -0.2, 4.0], [-1.0, 0.7, 6.0]])
    pix = project(X, K, np.eye(3), np.zeros(3))
    np.testing.assert_allclose(pix[0], [800 * 0.125 + 330, 780 * -0.05 + 250])
    np.testing.assert_allclose(normalize_points(pix, K), X[:, :2] / X[:, 2:])


def test_as_points2d_accepts_opencv_layout_and_rejects_others():
    assert as_points2d(np.zeros((5, 1, 2), np.float32)).shape == (5, 2)
    with pytest.raises(ValueError, match=r"`pts1` must have shape \(N, 2\), got \(5, 3\)"):
        as_points2d(np.zeros((5, 3)), "pts1")
    with pytest.raises(ValueError, match="non-finite"):
        as_points2d([[np.nan, 1.0]])


def test_distinct_correspondences_keep_the_first_of_each_in_order():
    pts1 = np.array([[1.0, 2.0], [3.0, 4.0], [1.0, 2.0], [1.0, 2.0], [5.0, 6.0]])
    pts2 = np.array([[7.0, 8.0], [9.0, 1.0], [7.0, 8.0], [7.5, 8.0], [2.0, 3.0]])
    # Row 2 repeats row 0; row 3 shares its image-1 pixel but not its match: kept.
    np.testing.assert_array_equal(distinct_correspondences(pts1, pts2), [0, 1, 3, 4])
    assert distinct_correspondences(np.zeros((0, 2)), np.zeros((0, 2))).shape == (0,)


def test_relative_pose_maps_camera_1_coordinates_into_camera_2():
    rng = np.random.default_rng(3)
    R1, R2 = rotation_about_axis([1, 2, 0.5], 20.0), rotation_about_axis([-0.3, 1, 0.2], -35.0)
    t1, t2 = rng.normal(size=3), rng.normal(size=3)
    world = rng.normal(size=(10, 3))
    R, t = relative_pose(R1, t1, R2, t2)
    cam1, cam2 = world @ R1.T + t1, world @ R2.T + t2
    np.testing.assert_allclose(cam1 @ R.T + t, cam2, atol=1e-12)
    R_back, t_back = relative_pose(R2, t2, R1, t1)  # the inverse motion
    np.testing.assert_allclose(R_back, R.T, atol=1e-12)
    np.testing.assert_allclose(t_back, -R.T @ t, atol=1e-12)
