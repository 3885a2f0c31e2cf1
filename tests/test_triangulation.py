import numpy as np
import pytest

from scene3D.evaluation.synthetic import random_points
from scene3D.geometry import project
from scene3D.geometry.triangulation import (
    behind_at_scene_parallax,
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


@pytest.mark.parametrize("angle_deg, baseline", [(8.0, 1.0), (20.0, 1.0), (3.0, 0.3)])
def test_random_matches_near_their_epipolar_lines_often_land_behind(camera, angle_deg,
                                                                   baseline):
    """Random matches that pass a 1 px inlier threshold of a right pose, among 300 right
    ones, lie behind a camera at the scene's parallax 19-44 % of the time, the right
    ones never: the ground of TwoViewSettings.max_behind_share (a fifth behind: about
    half the inliers or more wrong)."""
    from scene3D.evaluation.synthetic import asymmetric_pose
    from scene3D.geometry.epipolar import essential_distances, essential_from_pose

    R, t = asymmetric_pose(angle_deg, baseline)
    t = t / np.linalg.norm(t)
    _, right1, right2 = correspondences(camera, R, t, n=300, seed=1)
    rng = np.random.default_rng(0)
    p1, p2 = (rng.uniform([0, 0], [640, 480], (100_000, 2)) for _ in range(2))
    near = essential_distances(essential_from_pose(R, t), p1, p2, camera) < 1.0
    pts1, pts2 = np.vstack([right1, p1[near]]), np.vstack([right2, p2[near]])
    points = triangulate_points(pts1, pts2, camera, R, t)
    behind = behind_beyond_noise(points, R, t, camera, noise_px=0.3)
    angles = parallax_angles_deg(np.nan_to_num(points), R, t)
    counted = behind_at_scene_parallax(angles, behind, in_front_mask(points, R, t))
    assert near.sum() > 300
    assert not counted[:300].any()
    assert 0.15 < counted[300:].mean() < 0.5


def test_far_points_pushed_behind_by_a_wrong_focal_length_do_not_count(camera, true_pose):
    """A focal length 5 % short puts right matches of far points (1-100 km) behind the
    cameras, their rays nearly parallel (well beyond the noise's bound at 0.01 px):
    below a quarter of the scene's parallax they are not counted as wrong."""
    R, t = true_pose
    near_points = random_points(200, seed=3)
    far_points = random_points(100, seed=4, depth=(1e3, 1e5))
    points_true = np.vstack([near_points, far_points])
    pts1 = project(points_true, camera, np.eye(3), np.zeros(3))
    pts2 = project(points_true, camera, R, t)
    K_short = camera.copy()
    K_short[:2, :2] *= 0.95
    points = triangulate_points(pts1, pts2, K_short, R, t)
    behind = behind_beyond_noise(points, R, t, K_short, noise_px=0.01)
    assert behind[200:].mean() > 0.3  # the far ones cross infinity...
    angles = parallax_angles_deg(np.nan_to_num(points), R, t)
    counted = behind_at_scene_parallax(angles, behind, in_front_mask(points, R, t))
    assert not counted.any()  # ... at a parallax far below the scene's
