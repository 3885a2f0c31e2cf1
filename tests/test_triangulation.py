import numpy as np
import pytest

from scene3D.triangulation import (
    behind_beyond_noise,
    in_front_mask,
    parallax_angles_deg,
    reprojection_errors,
    triangulate_points,
)

from .helpers import correspondences


def test_noise_free_triangulation_is_exact(camera, true_pose):
    R, t = true_pose
    points, pts1, pts2 = correspondences(camera, R, t)
    est = triangulate_points(pts1, pts2, camera, R, t)
    np.testing.assert_allclose(est, points, rtol=1e-8)
    assert reprojection_errors(est, pts1, pts2, camera, R, t).max() < 1e-6
    assert in_front_mask(est, R, t).all()


def test_parallax_angle_of_a_known_point():
    # Cameras at the origin and at (2, 0, 0); the point (1, 0, 1) is seen under 90 degrees.
    R, t = np.eye(3), np.array([-2.0, 0.0, 0.0])
    angle = parallax_angles_deg(np.array([[1.0, 0.0, 1.0]]), R, t)
    assert angle[0] == pytest.approx(90.0)


def test_points_behind_a_camera_are_not_in_front():
    R, t = np.eye(3), np.array([-1.0, 0.0, 0.0])
    pts = np.array([[0.0, 0.0, 5.0], [0.0, 0.0, -5.0], [np.nan, 0.0, 1.0]])
    assert in_front_mask(pts, R, t).tolist() == [True, False, False]


def test_behind_beyond_noise_spares_points_at_infinity(camera):
    """A point behind a camera is a wrong match unless its rays are parallel within the
    noise (a far point that the noise moved across infinity)."""
    R, t = np.eye(3), np.array([-1.0, 0.0, 0.0])  # camera 2 one unit to the right
    f = 0.5 * (camera[0, 0] + camera[1, 1])
    points = np.array([
        [0.2, 0.1, 5.0],  # in front
        [0.2, 0.1, -5.0],  # behind both cameras, rays 11 degrees apart
        [0.0, 0.0, -1e4],  # behind, but at 0.006 degrees: within 3 sigma of 0.5 px
        [np.nan, np.nan, np.nan],  # at infinity
    ])
    flagged = behind_beyond_noise(points, R, t, camera, noise_px=0.5)
    assert flagged.tolist() == [False, True, False, False]
    # The same far point is flagged once its parallax exceeds three sigma of the noise.
    assert parallax_angles_deg(points[2:3], R, t)[0] > np.degrees(3 * np.sqrt(2) * 0.001 / f)
    assert behind_beyond_noise(points[2:3], R, t, camera, noise_px=0.001).tolist() == [True]
