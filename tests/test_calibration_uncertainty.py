"""Covariance of the intrinsics and the projection-uncertainty map: against OpenCV's standard
deviations, finite differences and a Monte-Carlo re-calibration."""

import cv2
import numpy as np
import pytest

from scene3D.calibration import BoardSpec, calibrate
from scene3D.calibration_uncertainty import (
    IntrinsicsCovariance,
    intrinsics_covariance,
    projection_covariance,
    projection_sigma_px,
    uncertainty_map,
    worst_direction_sigma,
)
from scene3D.imageio import read_image_size

from .helpers import detect_folder

# The map's key positions on a 640x480 image: centre, then the four corners.
KEY_PIXELS = np.array([[319.5, 239.5], [0.0, 0.0], [639.0, 0.0], [639.0, 479.0], [0.0, 479.0]])


@pytest.fixture(scope="module")
def left(chessboards):
    board = BoardSpec()
    dets = detect_folder(chessboards / "opencv-left", board)
    result = calibrate(dets, (640, 480), board, reject_outliers=False)
    return dets, result


def test_diagonal_equals_opencvs_standard_deviations(left):
    _, result = left
    std = result.covariance.std()
    assert result.covariance.names == ("fx", "fy", "cx", "cy", "k1", "k2", "p1", "p2", "k3")
    for name, value in result.std_intrinsics.items():
        assert std[name] == pytest.approx(value, rel=1e-6), name
    # Noise estimate: residuals over the degrees of freedom (2 x 702 - 9 - 6 x 13).
    assert result.covariance.dof == 2 * 13 * 54 - 9 - 6 * 13
    assert 0.5 * result.rms_px < result.covariance.residual_sigma_px < result.rms_px


def test_fixed_aspect_ratio_matches_opencv_too(left):
    dets, _ = left
    board = BoardSpec()
    result = calibrate(dets, (640, 480), board, flags=cv2.CALIB_FIX_ASPECT_RATIO,
                       reject_outliers=False)
    std = result.covariance.std()
    # OpenCV's free focal parameter is fy (it reports 0 for fx, which moves with it).
    assert result.std_intrinsics["fx"] == 0.0
    for name in ("fy", "cx", "cy", "k1", "k2", "p1", "p2", "k3"):
        assert std[name] == pytest.approx(result.std_intrinsics[name], rel=1e-6), name
    assert std["fx"] == pytest.approx(std["fy"] * result.K[0, 0] / result.K[1, 1], rel=1e-9)


def test_projection_jacobian_against_finite_differences(left):
    """The map's propagation: the projection of each pixel's ray under slightly changed
    intrinsics moves as the covariance's Jacobian says (a covariance with one parameter)."""
    _, result = left
    K, dist = result.K, result.dist
    names = result.covariance.names
    for k, step in ((0, 0.5), (2, 0.5), (4, 1e-4), (6, 1e-5), (8, 1e-4)):  # fx, cx, k1, p1, k3
        single = np.zeros((len(names), len(names)))
        single[k, k] = 1.0
        cov = IntrinsicsCovariance(names, single, 1.0, 1)
        predicted = np.sqrt(np.einsum("nii->n", projection_covariance(KEY_PIXELS, K, dist, cov)))
        theta = np.concatenate([[K[0, 0], K[1, 1], K[0, 2], K[1, 2]], dist])
        theta[k] += step
        K2 = np.array([[theta[0], 0, theta[2]], [0, theta[1], theta[3]], [0, 0, 1]])
        rays = cv2.undistortPoints(KEY_PIXELS.reshape(-1, 1, 2), K, dist, None, np.eye(3),
                                   np.eye(3), (3, 200, 1e-12)).reshape(-1, 2)
        rays = np.column_stack([rays, np.ones(len(rays))])
        moved = cv2.projectPoints(rays, np.zeros(3), np.zeros(3), K2, theta[4:])[0]
        observed = np.linalg.norm(moved.reshape(-1, 2) - KEY_PIXELS, axis=1) / step
        np.testing.assert_allclose(observed, predicted, rtol=2e-3, atol=1e-9, err_msg=names[k])


def test_pure_principal_point_uncertainty_is_uniform():
    """With only cx and cy uncertain (no distortion), every pixel moves alike."""
    names = ("fx", "fy", "cx", "cy", "k1", "k2", "p1", "p2", "k3")
    cov = np.zeros((9, 9))
    cov[2, 2], cov[3, 3] = 0.3 ** 2, 0.2 ** 2
    K = np.array([[600.0, 0, 330.0], [0, 590.0, 250.0], [0, 0, 1]])
    umap = uncertainty_map(K, np.zeros(5), IntrinsicsCovariance(names, cov, 0.2, 100),
                           (640, 480))
    np.testing.assert_allclose(umap.sigma_px, 0.3, rtol=1e-9)
    assert umap.warnings == []
    assert umap.xs[0] == 0 and umap.xs[-1] == 639 and umap.ys[-1] == 479


def test_worst_direction_sigma():
    cov = np.array([[[4.0, 0.0], [0.0, 1.0]], [[2.0, 2.0], [2.0, 2.0]]])
    np.testing.assert_allclose(worst_direction_sigma(cov), [2.0, 2.0])


def test_map_numbers_and_corner_warning(left):
    _, result = left
    umap = uncertainty_map(result.K, result.dist, result.covariance, (640, 480))
    assert umap.sigma_px.shape == (len(umap.ys), len(umap.xs))
    assert umap.centre_px < umap.median_px < umap.worst_px
    # The left*.jpg boards never reach the image corners: their uncertainty is large.
    assert min(umap.corners_px.values()) > 1.0
    assert umap.worst_px == pytest.approx(max(umap.corners_px.values()), rel=0.05)
    assert "exceeds 1 px" in umap.warnings[0]
    assert uncertainty_map(result.K, result.dist, result.covariance, (640, 480),
                           limit_px=100.0).warnings == []


def test_bad_inputs(left):
    dets, result = left
    with pytest.raises(ValueError, match="one entry per view"):
        intrinsics_covariance([d.object_points for d in dets], [], result.K, result.dist,
                              result.rvecs, result.tvecs)
    with pytest.raises(ValueError, match="flags"):
        intrinsics_covariance([d.object_points for d in dets], [d.image_points for d in dets],
                              result.K, result.dist, result.rvecs, result.tvecs,
                              flags=cv2.CALIB_USE_LU)
    with pytest.raises(ValueError, match="distortion"):
        projection_sigma_px(KEY_PIXELS, result.K, np.zeros(8), result.covariance)


def monte_carlo(folder, size, runs=200, seed=23):
    """The map's values at the centre and the four corners, and the spread a Monte-Carlo
    re-calibration gives there: corners made from the fitted model (board poses and
    intrinsics) plus Gaussian noise of the fitted sigma, calibrated again from the fit; each
    key pixel's camera-frame ray projected with the new intrinsics. Returns (predicted,
    empirical), each (5,) px (worst-direction 1 sigma)."""
    board = BoardSpec()
    dets = [d for d in detect_folder(folder, board)
            if read_image_size(folder / d.name) == size]
    result = calibrate(dets, size, board, reject_outliers=False)
    kept = [d for d in dets if d.name in result.per_view_errors_px]
    w, h = size
    pixels = np.array([[(w - 1) / 2, (h - 1) / 2], [0, 0], [w - 1, 0], [w - 1, h - 1],
                       [0, h - 1]], dtype=float)
    predicted = projection_sigma_px(pixels, result.K, result.dist, result.covariance)
    rays = cv2.undistortPoints(pixels.reshape(-1, 1, 2), result.K, result.dist, None,
                               np.eye(3), np.eye(3), (3, 200, 1e-12)).reshape(-1, 2)
    rays = np.column_stack([rays, np.ones(len(rays))])
    ideal = [cv2.projectPoints(d.object_points, r, t, result.K, result.dist)[0].reshape(-1, 2)
             for d, r, t in zip(kept, result.rvecs, result.tvecs)]
    object_points = [d.object_points.astype(np.float32) for d in kept]
    sigma = result.covariance.residual_sigma_px
    rng = np.random.default_rng(seed)
    projected = []
    for _ in range(runs):
        noisy = [(q + rng.normal(0, sigma, q.shape)).astype(np.float32).reshape(-1, 1, 2)
                 for q in ideal]
        _, K_mc, dist_mc, _, _ = cv2.calibrateCamera(
            object_points, noisy, size, result.K.copy(), result.dist.copy(),
            flags=cv2.CALIB_USE_INTRINSIC_GUESS)
        projected.append(cv2.projectPoints(rays, np.zeros(3), np.zeros(3), K_mc,
                                           dist_mc)[0].reshape(-1, 2))
    projected = np.array(projected)
    empirical = worst_direction_sigma(np.array([np.cov(projected[:, i].T)
                                                for i in range(len(pixels))]))
    return predicted, empirical


@pytest.mark.parametrize("folder, size", [("opencv-left", (640, 480)),
                                          ("udacity-lane-9x6", (1280, 720))])
def test_map_agrees_with_monte_carlo_recalibration(chessboards, folder, size):
    """Centre and the four corners within 20 % of a 200-run Monte-Carlo re-calibration."""
    predicted, empirical = monte_carlo(chessboards / folder, size)
    np.testing.assert_allclose(empirical, predicted, rtol=0.2)
