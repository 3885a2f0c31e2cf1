"""Radial lens distortion (scene3D.geometry.lens) and its bundle adjustment
(scene3D.optim.bundle.bundle_adjust_radial), on closed forms and synthetic views."""

import numpy as np
import pytest

from scene3D.evaluation.synthetic import orbit_poses
from scene3D.geometry.lens import (
    distort_normalized,
    distort_pixels,
    folds_within,
    max_shift_px,
    radial_coefficients,
    rescaled_coefficients,
    undistort_normalized,
    undistort_pixels,
)
from scene3D.optim.bundle import Observations
from scene3D.optim.bundle_radial import bundle_adjust_radial, radial_projection

K = np.array([[700.0, 0, 320.0], [0, 700.0, 240.0], [0, 0, 1]])


@pytest.mark.parametrize("k", [[-0.14], [0.06], [-0.25, 0.3], [0.0]])
def test_undistortion_inverts_distortion(k):
    rng = np.random.default_rng(0)
    xy = rng.uniform([0, 0], [640, 480], (500, 2))
    np.testing.assert_allclose(distort_pixels(undistort_pixels(xy, K, k), K, k), xy, atol=1e-9)
    n = rng.uniform(-0.5, 0.5, (500, 2))
    np.testing.assert_allclose(undistort_normalized(distort_normalized(n, k), k), n, atol=1e-12)


def test_distortion_closed_form():
    """``n (1 + k1 r^2 + k2 r^4)``: a point at radius 0.5 with k1 = -0.2, k2 = 0.1 moves
    to 0.5 (1 - 0.05 + 0.00625)."""
    np.testing.assert_allclose(distort_normalized([[0.3, 0.4]], [-0.2, 0.1]),
                               [[0.3 * 0.95625, 0.4 * 0.95625]], rtol=1e-15)


def test_beyond_the_fold_keeps_the_fold_radius():
    """A barrel lens's distorted radius stops growing at r_u^2 = -1 / (3 k1); farther
    pixels have no inverse and get that radius, not a wrapped-around one."""
    k1 = -0.5
    r_fold = np.sqrt(-1 / (3 * k1))
    beyond = distort_normalized([[r_fold, 0.0]], [k1])[0, 0] * 1.5
    assert undistort_normalized([[beyond, 0.0]], [k1])[0, 0] == pytest.approx(r_fold)


def test_rescaled_coefficients_are_the_same_camera():
    """Pixels undistorted with (f1, k) and then seen by a pinhole camera of focal length f2
    are those of the radial camera (f2, k'), exactly."""
    rng = np.random.default_rng(1)
    X = rng.uniform([-2, -1.5, 4], [2, 1.5, 6], (200, 3))
    f1, f2, k = 700.0, 730.0, np.array([-0.12, 0.05])
    K2 = np.diag([f2, f2, 1.0])
    K2[:2, 2] = K[:2, 2]
    n = X[:, :2] / X[:, 2:]
    # The camera (f1, k) photographs pixels p; the pinhole camera f2 sees them undistorted.
    photographed = distort_normalized(n * f2 / f1, k) * f1 + K[:2, 2]
    k2 = rescaled_coefficients(k, f1, f2)
    np.testing.assert_allclose(distort_normalized(n, k2) * f2 + K[:2, 2], photographed,
                               atol=1e-9)


def test_a_lens_that_folds_inside_the_image_is_seen():
    """k1 = -0.5 folds at r_u^2 = 2/3, distorted radius 0.544; the corner of 640x480 under
    f = 700 is at 0.571: it folds inside. A photo's lens (-0.14) and a pincushion do not."""
    assert folds_within(K, [-0.5], (640, 480))
    assert not folds_within(K, [-0.14], (640, 480)) and not folds_within(K, [0.3], (640, 480))
    K_small = np.array([[700.0, 0, 159.5], [0, 700.0, 119.5], [0, 0, 1]])
    assert not folds_within(K_small, [-0.5], (320, 240))  # corners at 0.29: inside the fold


def test_camera_models_and_corner_shift():
    assert [radial_coefficients(m) for m in ("pinhole", "simple_radial", "radial")] == [0, 1, 2]
    with pytest.raises(ValueError, match="unknown camera model 'fisheye'"):
        radial_coefficients("fisheye")
    assert max_shift_px(K, [0.0], (640, 480)) == 0.0
    # The corner (0, 0) is 400 px from the centre: photographed at radius 400/700, it
    # comes from r_u with r_u (1 - 0.1 r_u^2) = 0.5714, r_u = 0.59220: 14.5 px farther out.
    assert max_shift_px(K, [-0.1], (640, 480)) == pytest.approx(700 * (0.59220 - 400 / 700),
                                                               abs=0.01)


def _orbit(k_true, noise_px, views=10, points=800, seed=0):
    rng = np.random.default_rng(seed)
    Rs, ts = orbit_poses(views)
    X = rng.uniform([-8, -4, -8], [8, 2, 8], (points, 3))
    view = np.repeat(np.arange(views), points)
    point = np.tile(np.arange(points), views)
    obs = Observations(view, point, np.zeros((len(view), 2)))
    pix = radial_projection(Rs, ts, X, obs, K, np.asarray(k_true))[0]
    cam = np.einsum("oij,oj->oi", Rs[view], X[point]) + ts[view]
    pinhole = cam[:, :2] / cam[:, 2:] * K[0, 0] + K[:2, 2]
    # In the image with the lens and without it: a point far outside the field of view
    # can fold back into a barrel lens's image (the model is no lens there).
    seen = (cam[:, 2] > 0) & np.all((pix > 0) & (pix < [640, 480]) & (pinhole > -100)
                                    & (pinhole < [740, 580]), axis=1)
    keep = seen & (np.bincount(point[seen], minlength=points)[point] >= 2)
    xy = pix[keep] + rng.normal(0, noise_px, (int(keep.sum()), 2))
    return Rs, ts, X, Observations(view[keep], point[keep], xy)


def test_radial_projection_derivatives():
    Rs, ts, X, obs = _orbit([-0.1, 0.02], 0.0, views=4, points=100)
    k = np.array([-0.1, 0.02])
    p0, J_camera, J_point, J_global = radial_projection(Rs, ts, X, obs, K, k)
    eps = 1e-6
    for i in range(2):
        step = k.copy()
        step[i] += eps
        numeric = (radial_projection(Rs, ts, X, obs, K, step)[0] - p0) / eps
        np.testing.assert_allclose(numeric, J_global[:, :, 1 + i], atol=1e-4)
    K_longer = K.copy()
    K_longer[:2, :2] *= np.exp(eps)
    numeric = (radial_projection(Rs, ts, X, obs, K_longer, k)[0] - p0) / eps
    np.testing.assert_allclose(numeric, J_global[:, :, 0], atol=2e-3)
    moved = X.copy()
    moved[:, 2] += eps
    numeric = (radial_projection(Rs, ts, moved, obs, K, k)[0] - p0) / eps
    np.testing.assert_allclose(numeric, J_point[:, :, 2], atol=1e-3)
    shifted = ts.copy()
    shifted[:, 0] += eps
    numeric = (radial_projection(Rs, shifted, X, obs, K, k)[0] - p0) / eps
    np.testing.assert_allclose(numeric, J_camera[:, :, 3], atol=1e-3)


@pytest.mark.parametrize("k_true", [[-0.14], [0.05], [-0.2, 0.08]])
def test_bundle_adjustment_finds_the_lens(k_true):
    """From a focal length 7 % off and no distortion, exact observations: the focal
    length and the coefficients come back to 1e-6; with 0.5 px noise within 4 of their
    standard deviations."""
    for noise in (0.0, 0.5):
        Rs, ts, X, obs = _orbit(k_true, noise)
        K0 = K.copy()
        K0[:2, :2] *= 1.07
        rng = np.random.default_rng(2)
        t_start = ts + rng.normal(0, 0.02, ts.shape) * (np.arange(len(ts)) > 1)[:, None]
        fit = bundle_adjust_radial(Rs, t_start, X + rng.normal(0, 0.02, X.shape), obs, K0,
                                   np.zeros(len(k_true)), [0, 1], 749.0, 0.5,
                                   loss="linear", max_iterations=100, tolerance=1e-15)
        errors = np.concatenate([[np.log(fit.K[0, 0] / 700.0)], fit.k - k_true])
        if noise == 0.0:
            np.testing.assert_allclose(errors, 0.0, atol=1e-6)
            assert fit.noise_px <= 1e-6  # the floor of its robust estimate
        else:
            assert np.all(np.abs(errors) < 4 * fit.sigma), (errors, fit.sigma)
            # Below the true 0.5 px: the adjustment fits part of the noise (a point
            # seen twice keeps one of its four degrees of freedom in the residuals).
            assert 0.2 < fit.noise_px < 0.55


def test_bundle_adjustment_refuses_bad_input():
    Rs, ts, X, obs = _orbit([-0.1], 0.0, views=3, points=50)
    with pytest.raises(ValueError, match="one or two radial coefficients"):
        bundle_adjust_radial(Rs, ts, X, obs, K, np.zeros(3), 0, 700.0, 0.5)
    with pytest.raises(ValueError, match="priors must be positive"):
        bundle_adjust_radial(Rs, ts, X, obs, K, np.zeros(1), 0, -1.0, 0.5)
