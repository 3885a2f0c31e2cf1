import numpy as np
import pytest

from scene3D.epipolar import (
    epipolar_lines,
    epipolar_residuals,
    essential_from_pose,
    estimate_essential,
    estimate_fundamental,
    fundamental_from_essential,
)
from scene3D.geometry import normalize_points, to_homogeneous
from scene3D.pose import choose_pose

from .helpers import correspondences


def _same_up_to_sign(A, B, atol):
    A = A / np.linalg.norm(A)
    B = B / np.linalg.norm(B)
    return min(np.abs(A - B).max(), np.abs(A + B).max()) < atol


def test_fundamental_satisfies_the_epipolar_constraint(camera, true_pose):
    R, t = true_pose
    _, pts1, pts2 = correspondences(camera, R, t)
    F, inliers = estimate_fundamental(pts1, pts2)
    assert inliers.all()
    assert np.linalg.matrix_rank(F, tol=1e-9) == 2
    assert epipolar_residuals(F, pts1, pts2).max() < 1e-8
    F_true = fundamental_from_essential(essential_from_pose(R, t), camera)
    assert _same_up_to_sign(F, F_true, 1e-6)


def test_essential_satisfies_its_constraint_and_matches_the_truth(camera, true_pose):
    R, t = true_pose
    _, pts1, pts2 = correspondences(camera, R, t)
    E, inliers = estimate_essential(pts1, pts2, camera)
    assert inliers.all()
    x1 = to_homogeneous(normalize_points(pts1, camera))
    x2 = to_homogeneous(normalize_points(pts2, camera))
    assert np.abs(np.sum(x2 * (x1 @ E.T), axis=1)).max() < 1e-8
    s = np.linalg.svd(E, compute_uv=False)
    assert s[0] == pytest.approx(s[1], rel=1e-6) and s[2] < 1e-8
    assert _same_up_to_sign(E, essential_from_pose(R, t), 1e-6)


def test_essential_rejects_outliers(camera, true_pose):
    R, t = true_pose
    _, pts1, pts2 = correspondences(camera, R, t, n=300, noise_px=0.3)
    rng = np.random.default_rng(5)
    bad = rng.choice(300, 60, replace=False)
    pts2[bad] = rng.uniform(0, 640, (60, 2))
    _, inliers = estimate_essential(pts1, pts2, camera)
    assert not inliers[bad].any() or inliers[bad].sum() <= 3
    assert inliers.sum() >= 230


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_noisy_points_give_an_accurate_pose(camera, true_pose, seed):
    from scene3D.evaluation import relative_pose_error

    R, t = true_pose
    _, pts1, pts2 = correspondences(camera, R, t, n=300, noise_px=0.5, seed=seed)
    E, inliers = estimate_essential(pts1, pts2, camera)
    R_est, t_est, _, _ = choose_pose(E, pts1[inliers], pts2[inliers], camera)
    err = relative_pose_error(R_est, t_est, R, t)
    assert err.rotation_deg < 0.5
    assert err.translation_deg < 2.0


def test_epipolar_lines_pass_through_the_matches(camera, true_pose):
    R, t = true_pose
    _, pts1, pts2 = correspondences(camera, R, t, n=10)
    F = fundamental_from_essential(essential_from_pose(R, t), camera)
    lines2 = epipolar_lines(F, pts1, which_image=1)
    lines1 = epipolar_lines(F, pts2, which_image=2)
    np.testing.assert_allclose(np.sum(lines2 * to_homogeneous(pts2), axis=1), 0, atol=1e-8)
    np.testing.assert_allclose(np.sum(lines1 * to_homogeneous(pts1), axis=1), 0, atol=1e-8)
    with pytest.raises(ValueError, match="which_image"):
        epipolar_lines(F, pts1, which_image=3)


def test_bad_inputs_are_named(camera):
    with pytest.raises(ValueError, match="same length"):
        estimate_essential(np.zeros((10, 2)), np.zeros((9, 2)), camera)
    with pytest.raises(ValueError, match="at least 8"):
        estimate_fundamental(np.zeros((5, 2)), np.zeros((5, 2)))
    with pytest.raises(ValueError, match=r"`K` must have shape \(3, 3\)"):
        estimate_essential(np.zeros((10, 2)), np.zeros((10, 2)), np.eye(2))
