import numpy as np
import pytest

from scene3D.geometry import to_homogeneous
from scene3D.geometry.epipolar import (
    epipolar_lines,
    epipolar_residuals,
    essential_from_pose,
    estimate_fundamental,
    fundamental_from_essential,
)
from scene3D.twoview.essential_fit import estimate_essential

from .helpers import correspondences, same_up_to_sign


def test_fundamental_satisfies_the_epipolar_constraint(camera, true_pose):
    R, t = true_pose
    _, pts1, pts2 = correspondences(camera, R, t)
    F, inliers = estimate_fundamental(pts1, pts2)
    assert inliers.all()
    assert np.linalg.matrix_rank(F, tol=1e-9) == 2
    assert epipolar_residuals(F, pts1, pts2).max() < 1e-8
    F_true = fundamental_from_essential(essential_from_pose(R, t), camera)
    assert same_up_to_sign(F, F_true, 1e-6)


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
