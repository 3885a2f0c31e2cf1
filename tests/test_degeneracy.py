import numpy as np
import pytest

from scene3D.evaluation.synthetic import random_points
from scene3D.geometry import project, rotation_error_deg
from scene3D.geometry.epipolar import essential_distances, essential_from_pose, estimate_homography
from scene3D.twoview.degeneracy import (
    fit_rotation,
    fit_rotation_and_focal,
    gric,
    homography_errors,
    motion_model_choice,
)
from scene3D.twoview.essential_fit import noise_sigma_px

from .helpers import correspondences


def test_fit_rotation_is_exact_for_a_camera_that_only_turned(camera, true_pose):
    R, _ = true_pose
    _, pts1, pts2 = correspondences(camera, R, np.zeros(3), n=100)
    R_fit = fit_rotation(pts1, pts2, camera)
    assert rotation_error_deg(R_fit, R) < 1e-8
    H = camera @ R_fit @ np.linalg.inv(camera)
    assert homography_errors(H, pts1, pts2).max() < 1e-6


@pytest.mark.parametrize("factor", [0.6, 0.8, 1.3, 1.8])
def test_fit_rotation_and_focal_finds_the_zoom_a_rotation_was_seen_through(camera, true_pose,
                                                                           factor):
    R, _ = true_pose
    _, pts1, pts2 = correspondences(camera, R, np.zeros(3), n=100)
    K = camera.copy()
    K[:2, :2] *= factor
    R_fit, scale = fit_rotation_and_focal(pts1, pts2, K, 1.0)
    assert scale == pytest.approx(1.0 / factor, rel=1e-6)
    assert rotation_error_deg(R_fit, R) < 1e-6


def _motion_choice(K, pts1, pts2, R, t, free_focal, noise_px=0.3):
    """The choice with the noise known (a translation's Sampson distances under a wrong
    focal length would measure more)."""
    distances = essential_distances(essential_from_pose(R, t), pts1, pts2, K)
    H, _ = estimate_homography(pts1, pts2)
    return motion_model_choice(pts1, pts2, K, distances, noise_px, H, free_focal)


def test_a_rotation_under_another_focal_length_is_told_from_a_baseline(camera, true_pose):
    """With ``free_focal``, a camera that only turned, seen through a calibration 1.3
    times too long, is a rotation under a focal length 1 / 1.3 times K's; a real
    baseline is not, and without ``free_focal`` nothing is fitted."""
    R, t = true_pose
    K = camera.copy()
    K[:2, :2] *= 1.3
    _, pts1, pts2 = correspondences(camera, R, np.zeros(3), n=300, noise_px=0.3)
    turned = _motion_choice(K, pts1, pts2, R, t, free_focal=True)
    assert turned.focal_scale == pytest.approx(1 / 1.3, rel=0.01)
    assert turned.focal_rotation_share > 0.95 > turned.rotation_share
    assert _motion_choice(K, pts1, pts2, R, t, free_focal=False).focal_rotation_share == 0.0
    _, pts1, pts2 = correspondences(camera, R, t, n=300, noise_px=0.3)
    moved = _motion_choice(camera, pts1, pts2, R, t, free_focal=True)
    assert moved.focal_rotation_share < 0.2 and not moved.pure_rotation


def test_gric_counts_the_dimension_and_the_parameters():
    errors = np.zeros(100)
    # n d log 4 + k log(4 n); residuals beyond the cap cost 2 (4 - d) each.
    assert gric(errors, 1.0, 3, 5) == pytest.approx(100 * 3 * np.log(4) + 5 * np.log(400))
    assert gric(np.full(100, 10.0), 1.0, 2, 3) - gric(errors, 1.0, 2, 3) == pytest.approx(400)


def _choice(camera, R, t, noise_px, points=None, seed=0):
    points = random_points(300, seed) if points is None else points
    rng = np.random.default_rng(seed + 1)
    pts1 = project(points, camera, np.eye(3), np.zeros(3)) + rng.normal(0, noise_px,
                                                                         (len(points), 2))
    pts2 = project(points, camera, R, t) + rng.normal(0, noise_px, (len(points), 2))
    E = essential_from_pose(R, t if np.linalg.norm(t) else np.array([1.0, 0.0, 0.0]))
    distances = essential_distances(E, pts1, pts2, camera)
    H, _ = estimate_homography(pts1, pts2)
    return motion_model_choice(pts1, pts2, camera, distances, noise_sigma_px(distances), H)


def test_model_selection_tells_a_rotation_from_a_short_baseline(camera, true_pose):
    R, t = true_pose
    rotation = _choice(camera, R, np.zeros(3), 0.3)
    assert rotation.pure_rotation and rotation.rotation_gric < rotation.essential_gric
    assert rotation_error_deg(rotation.R, R) < 0.05
    short = _choice(camera, R, 0.05 * t, 0.3)  # 0.6 deg of parallax
    assert not short.pure_rotation and not short.planar
    wide = _choice(camera, R, t, 0.3)
    assert not wide.pure_rotation and not wide.planar
    # Every match beyond the rotation's cap: 300 x (4 + 2 log 4 - 1 - 3 log 4) ~ 480 apart.
    assert wide.essential_gric < wide.rotation_gric - 400


def test_model_selection_sees_a_plane(camera, true_pose):
    R, t = true_pose
    rng = np.random.default_rng(2)
    xy = rng.uniform(-3, 3, (300, 2))
    plane = np.column_stack([xy, 7.0 + 0.2 * xy[:, 0]])
    choice = _choice(camera, R, t, 0.3, points=plane)
    assert choice.planar and not choice.pure_rotation


def _still_camera_and_a_moving_object(camera, R, moving=100, still=300, noise_px=0.2, seed=0):
    """A camera that only turned (by R), and an object in view that moved by 0.5 units."""
    rng = np.random.default_rng(seed)
    scene = random_points(still, seed)
    thing = random_points(moving, seed + 1, depth=(3.0, 5.0))
    moved = thing + np.array([0.4, 0.1, 0.3])
    pts1 = project(np.vstack([scene, thing]), camera, np.eye(3), np.zeros(3))
    pts2 = np.vstack([project(scene, camera, R, np.zeros(3)),
                      project(moved, camera, R, np.zeros(3))])
    return (pts1 + rng.normal(0, noise_px, pts1.shape),
            pts2 + rng.normal(0, noise_px, pts2.shape))


def test_fit_rotation_is_not_pulled_by_a_moving_object(camera, true_pose):
    R, _ = true_pose
    pts1, pts2 = _still_camera_and_a_moving_object(camera, R)
    H, _ = estimate_homography(pts1, pts2)
    assert rotation_error_deg(fit_rotation(pts1, pts2, camera, 0.6, H), R) < 0.02


def test_a_still_camera_with_a_moving_object_is_not_trusted(camera, true_pose):
    """An essential matrix explains the still scene (for any translation) and the moving
    object (the translation is its motion) together, and it explains them better than
    the rotation: a pose comes back, pinned by the object. Three quarters of the matches
    show no parallax, so it is untrusted, whatever its covariance says."""
    from scene3D.errors import ReconstructionError
    from scene3D.twoview import reconstruct_from_matches

    R, _ = true_pose
    pts1, pts2 = _still_camera_and_a_moving_object(camera, R)
    try:
        result = reconstruct_from_matches(pts1, pts2, camera)
    except ReconstructionError as exc:  # refused is as good
        assert exc.reason == "no_parallax"
        return
    assert not result.trusted
    assert any("a rotation alone explains 7" in w and "moving object" in w
               for w in result.warnings)
