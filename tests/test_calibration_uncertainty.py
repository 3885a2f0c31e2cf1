"""Covariance of the intrinsics and the projection-uncertainty map: against OpenCV's standard
deviations, finite differences and a Monte-Carlo re-calibration."""

import cv2
import numpy as np
import pytest

from scene3D.calibration import BoardSpec, Detection, calibrate
from scene3D.calibration.uncertainty import (
    IntrinsicsCovariance,
    intrinsics_covariance,
    projection_covariance,
    projection_sigma_px,
    reached_by_rays,
    uncertainty_map,
    worst_direction_sigma,
)
from scene3D.io.images import read_image_size

from .helpers import detect_folder

# The map's key positions on a 640x480 image: centre, then the four corners.
KEY_PIXELS = np.array([[319.5, 239.5], [0.0, 0.0], [639.0, 0.0], [639.0, 479.0], [0.0, 479.0]])


@pytest.fixture(scope="module")
def left(chessboards):
    board = BoardSpec()
    dets = detect_folder(chessboards / "opencv-left", board)
    result = calibrate(dets, (640, 480), board, reject_outliers=False)
    return dets, result


def _opencv_std(dets, size, flags=0):
    """OpenCV's ``stdDeviationsIntrinsics`` for the same views, by name."""
    out = cv2.calibrateCameraExtended([d.object_points.astype(np.float32) for d in dets],
                                      [d.image_points.astype(np.float32) for d in dets],
                                      size, None, None, flags=flags)
    names = ("fx", "fy", "cx", "cy", "k1", "k2", "p1", "p2", "k3")
    return dict(zip(names, out[5].ravel()))


def test_diagonal_equals_opencvs_standard_deviations(left):
    dets, result = left
    std = result.covariance.std()
    assert result.covariance.names == ("fx", "fy", "cx", "cy", "k1", "k2", "p1", "p2", "k3")
    assert result.std_intrinsics == std  # what the CLI prints and saves
    for name, value in _opencv_std(dets, (640, 480)).items():
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
    opencv = _opencv_std(dets, (640, 480), cv2.CALIB_FIX_ASPECT_RATIO)
    # OpenCV's free focal parameter is fy (it reports 0 for fx, which moves with it).
    assert opencv["fx"] == 0.0
    for name in ("fy", "cx", "cy", "k1", "k2", "p1", "p2", "k3"):
        assert std[name] == pytest.approx(opencv[name], rel=1e-6), name
    assert std["fx"] == pytest.approx(std["fy"] * result.K[0, 0] / result.K[1, 1], rel=1e-9)
    assert result.std_intrinsics == std


@pytest.mark.parametrize("seed", [0, 3, 7])
def test_a_telephoto_lens_gets_honest_sigmas_where_opencvs_are_not(seed):
    """A 4000 px lens on 640x480 views tilted by up to 35 deg (corners exact plus 0.05 px
    noise): r < 0.1, so k2 and k3 (of r^4 and r^6) are barely determined and come out far
    from the true 0. OpenCV's standard deviation of k3 puts it 10^4-10^5 sigmas off; the
    covariance's, which std_intrinsics reports, within three (the inversion scaled: the
    unscaled pseudo-inverse gave k3 the same tiny variance as OpenCV)."""
    K = np.array([[4000.0, 0, 318], [0, 4000, 244], [0, 0, 1]])
    board = BoardSpec()
    grid = board.grid_object_points()
    rng = np.random.default_rng(seed)
    dets = []
    for i in range(12):
        rvec = np.deg2rad(rng.uniform(-35, 35, 3)) * [1, 1, 0.3]
        tvec = np.array([rng.uniform(-0.5, 0.5), rng.uniform(-0.4, 0.4), 75.0]) - \
            cv2.Rodrigues(rvec)[0] @ grid.mean(axis=0)
        pixels = cv2.projectPoints(grid, rvec, tvec, K, np.array([0.05, 0, 0, 0, 0]))[0]
        pixels = pixels.reshape(-1, 2) + rng.normal(0, 0.05, (len(grid), 2))
        dets.append(Detection(f"v{i}", pixels, grid, "synthetic"))
    result = calibrate(dets, (640, 480), board, reject_outliers=False)
    errors = {"fx": result.K[0, 0] - 4000, "cx": result.K[0, 2] - 318,
              "k1": result.dist[0] - 0.05, "k2": result.dist[1], "k3": result.dist[4]}
    for name, error in errors.items():
        assert abs(error) < 3 * result.std_intrinsics[name], name
    assert abs(errors["k3"]) > 1000 * _opencv_std(dets, (640, 480))["k3"]


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


def test_a_distortion_that_folds_inside_the_image_leaves_its_corners_blank():
    """k1 = -0.30, k2 = 0.21, k3 = -0.21 (a 3-view fit to OpenCV's left*.jpg): the
    distorted radius peaks at 0.70 of the focal length, the corners lie at 0.79. No ray
    reaches them; the map says so rather than give them a number."""
    K = np.array([[534.0, 0, 340.0], [0, 534.0, 236.0], [0, 0, 1]])
    dist = np.array([-0.301, 0.206, 0.0, 0.0, -0.214])
    reached = reached_by_rays(KEY_PIXELS, K, dist)
    assert reached.tolist() == [True, False, False, False, False]
    assert reached_by_rays(KEY_PIXELS, K, np.array([-0.28, 0.05, 0, 0, 0.1])).all()
    names = ("fx", "fy", "cx", "cy", "k1", "k2", "p1", "p2", "k3")
    cov = np.diag([0.4, 0.4, 0.4, 0.4, 1e-5, 1e-4, 1e-8, 1e-8, 1e-4]) ** 2
    umap = uncertainty_map(K, dist, IntrinsicsCovariance(names, cov, 0.2, 100), (640, 480))
    assert 0 < umap.unreachable_share < 0.1
    assert all(np.isnan(v) for v in umap.corners_px.values())
    assert np.isfinite(umap.median_px) and np.isfinite(umap.worst_px)
    assert umap.warnings[0].startswith("the fitted distortion folds back inside the image")
    assert "top-left, top-right, bottom-right, bottom-left corners" in umap.warnings[0]


def test_an_uncertain_centre_is_not_blamed_on_the_corners():
    """Only cx and cy uncertain, by 3 px: the map is 3 px everywhere; the advice is about
    the intrinsics, not about views in the corners."""
    names = ("fx", "fy", "cx", "cy", "k1", "k2", "p1", "p2", "k3")
    cov = np.zeros((9, 9))
    cov[2, 2] = cov[3, 3] = 3.0 ** 2
    K = np.array([[600.0, 0, 330.0], [0, 590.0, 250.0], [0, 0, 1]])
    (warning,) = uncertainty_map(K, np.zeros(5), IntrinsicsCovariance(names, cov, 0.2, 100),
                                 (640, 480)).warnings
    assert warning.startswith("the projection uncertainty exceeds 1 px even at the image "
                              "centre (3.00 px")
    assert "tilted" in warning and "in the corners" not in warning


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
