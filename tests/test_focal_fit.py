import warnings

import cv2
import numpy as np
import pytest

from scene3D.evaluation import relative_pose_error
from scene3D.features import find_matches
from scene3D.geometry import to_homogeneous
from scene3D.geometry.epipolar import sampson_jacobian, sampson_residuals_homogeneous
from scene3D.optim.refinement import refine_relative_pose
from scene3D.optim.uncertainty import tangent_basis, update_pose
from scene3D.twoview import reconstruct_two_view
from scene3D.twoview.focal_fit import (
    COMMON,
    MAX_LOG_SCALE,
    RATIO,
    fit_focal_ratio,
    fit_focal_scale,
    focal_fundamental_derivatives,
    scaled_fundamental,
)

from .helpers import correspondences, perturbed_pose, project, random_points, strecha_pair


@pytest.mark.parametrize("weights", [COMMON, RATIO])
def test_focal_jacobian_matches_finite_differences(camera, true_pose, weights):
    R, t = perturbed_pose(*true_pose, angle_deg=3.0)
    _, pts1, pts2 = correspondences(camera, *true_pose, n=50, noise_px=2.0)
    h1, h2 = to_homogeneous(pts1), to_homogeneous(pts2)
    K_inv, log_s = np.linalg.inv(camera), 0.2

    def sampson_at(x):
        R_, t_ = update_pose(R, t, x[:5], basis)
        F = scaled_fundamental(R_, t_, log_s + x[5], weights, K_inv)
        return sampson_residuals_homogeneous(F, h1, h2)

    basis = tangent_basis(t)
    J = sampson_jacobian(scaled_fundamental(R, t, log_s, weights, K_inv),
                         focal_fundamental_derivatives(R, t, log_s, weights, basis, K_inv),
                         h1, h2)
    step = 1e-6
    numeric = np.stack([(sampson_at(step * e) - sampson_at(-step * e)) / (2 * step)
                        for e in np.eye(6)], axis=1)
    np.testing.assert_allclose(J, numeric, rtol=1e-5, atol=1e-6 * np.abs(numeric).max())


@pytest.mark.parametrize("factor", [0.7, 1.0, 1.5])
def test_focal_scale_recovers_a_wrong_calibration_exactly(camera, true_pose, factor):
    # The images are from `camera`; the "calibration" has its focal lengths times `factor`.
    R, t = true_pose
    _, pts1, pts2 = correspondences(camera, R, t, n=200)
    wrong = camera.copy()
    wrong[:2, :2] *= factor
    R0, t0 = refine_relative_pose(R, t, pts1, pts2, wrong, loss="linear")  # the best it can
    fit = fit_focal_scale(R0, t0, pts1, pts2, wrong, loss="linear")
    assert fit.scale == pytest.approx(1.0 / factor, rel=1e-6)
    assert fit.sigma_log < 1e-6  # exact correspondences: no doubt left


def test_focal_scale_is_undetermined_without_rotation(camera):
    # A pure translation: x2 ~ K_s t' for every s, so no focal length fits better.
    R, t = np.eye(3), np.array([0.8, 0.1, 0.2])
    _, pts1, pts2 = correspondences(camera, R, t, n=200, noise_px=0.3)
    fit = fit_focal_scale(R, t / np.linalg.norm(t), pts1, pts2, camera)
    assert fit.sigma_log > 0.3 or not np.isfinite(fit.sigma_log)


@pytest.mark.parametrize("zoom", [0.8, 1.0, 1.25])
def test_focal_ratio_recovers_two_zoom_settings_exactly(camera, true_pose, zoom):
    # Image 2's focal length `zoom` times image 1's, their geometric mean the calibration's.
    R, t = true_pose
    points = random_points(200, 0)
    pts1 = project(points, camera @ np.diag([zoom**-0.5, zoom**-0.5, 1]), np.eye(3), np.zeros(3))
    pts2 = project(points, camera @ np.diag([zoom**0.5, zoom**0.5, 1]), R, t)
    R0, t0 = refine_relative_pose(R, t, pts1, pts2, camera, loss="linear")  # the best one K gives
    fit = fit_focal_ratio(R0, t0, pts1, pts2, camera, loss="linear")
    assert fit.scale == pytest.approx(zoom, rel=1e-6)
    assert fit.sigma_log < 1e-6
    np.testing.assert_allclose(fit.R, R, atol=1e-6)
    np.testing.assert_allclose(fit.t, t / np.linalg.norm(t), atol=1e-6)


def test_focal_fit_fundamental_is_the_fitted_geometry(camera, true_pose):
    R, t = true_pose
    _, pts1, pts2 = correspondences(camera, R, t, n=50)
    fit = fit_focal_ratio(R, t, pts1, pts2, camera)
    distances = np.abs(sampson_residuals_homogeneous(fit.fundamental(camera),
                                                     to_homogeneous(pts1), to_homogeneous(pts2)))
    assert distances.max() < 1e-6


def test_image_2_at_another_zoom_with_one_calibration_is_flagged(fountain):
    """fountain-P11 5-6 at 768 px, image 2 zoomed to 0.85 (a zoom lens turned between the
    shots) with one K for both: the pose comes out 37 deg off in translation direction,
    the zoom taken for a move along the optical axis, with sigmas of 0.1 deg and the common
    focal factor undetermined. The ratio of the two focal lengths is not."""
    scene, truth = strecha_pair(fountain, 5, 6, 768)
    h, w = scene.img2.shape[:2]
    zoom = np.array([[0.85, 0, w / 2 * 0.15], [0, 0.85, h / 2 * 0.15]])
    img2 = cv2.warpAffine(scene.img2, zoom, (w, h), flags=cv2.INTER_AREA)
    result = reconstruct_two_view(scene.img1, find_matches(scene.img1, img2), scene.K)
    assert relative_pose_error(result.R, result.t, *truth).max_deg > 20
    assert result.focal_ratio == pytest.approx(0.85, abs=0.01)
    assert not result.trusted
    assert any("image 2 with a focal length 0.85 times" in w for w in result.warnings)
    right = scene.reconstruct("SIFT")
    assert right.trusted and right.focal_ratio == pytest.approx(1.0, abs=0.02)


@pytest.mark.parametrize("fit", [fit_focal_scale, fit_focal_ratio])
def test_matches_that_fit_no_geometry_do_not_overflow(camera, true_pose, fit):
    """Random matches: the steps ran on until exp overflowed, and RuntimeWarnings reached
    the user (an ORB sweep of a review). The fit now stays within MAX_LOG_SCALE."""
    R, t = true_pose
    for seed in range(20):
        rng = np.random.default_rng(seed)
        pts1, pts2 = rng.uniform(0, 640, (40, 2)), rng.uniform(0, 480, (40, 2))
        with warnings.catch_warnings():
            warnings.simplefilter("error")
            result = fit(R, t, pts1, pts2, camera)
        assert abs(np.log(result.scale)) <= MAX_LOG_SCALE
