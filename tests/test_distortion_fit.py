"""The distortion check: the pose refined with one radial distortion of the lens
(scene3D.twoview.distortion_fit) and the doubt it raises
(scene3D.twoview.trust.distortion_warning)."""

import cv2
import numpy as np
import pytest

from scene3D.evaluation import relative_pose_error
from scene3D.evaluation.synthetic import lens_photo
from scene3D.features import find_matches
from scene3D.geometry import pose_angle_deg, project, rotation_about_axis, skew, to_homogeneous
from scene3D.geometry.camera import scale_intrinsics_halved
from scene3D.geometry.epipolar import fundamental_derivatives
from scene3D.io.datasets import read_strecha_camera, relative_pose
from scene3D.io.images import load_working_image
from scene3D.optim.refinement import refine_relative_pose
from scene3D.optim.uncertainty import tangent_basis, update_pose
from scene3D.selfcalibration import self_calibrate_pair
from scene3D.twoview import TwoViewSettings, reconstruct_from_matches, reconstruct_two_view
from scene3D.twoview.distortion_fit import (
    DistortionFit,
    fit_radial_distortion,
    observed_sampson,
    observed_sampson_jacobian,
    undistort_division,
    undistort_homogeneous,
)
from scene3D.twoview.trust import distortion_warning

from .helpers import correspondences, perturbed_pose


def distorted_pixels(pts, K, k):
    """The pixels a lens of division-model coefficient ``k`` shows for the pinhole pixels
    ``pts``: the inverse of ``undistort_division``, by fixed-point iteration."""
    c, f = K[:2, 2], np.diag(K)[:2]
    x_u = (pts - c) / f
    x_d = x_u.copy()
    for _ in range(100):
        x_d = x_u * (1.0 + k * np.sum(x_d**2, axis=1))[:, None]
    return c + x_d * f


def test_undistort_division_inverts_the_lens(camera):
    pts = np.array([[0.0, 0.0], [639.0, 479.0], [320.0, 240.0], [100.0, 400.0]])
    for k in (-0.2, 0.0, 0.1):
        np.testing.assert_allclose(undistort_division(distorted_pixels(pts, camera, k), camera, k),
                                   pts, atol=1e-9)


@pytest.mark.parametrize("k", [0.0, -0.08, 0.1])
def test_distortion_jacobian_matches_finite_differences(camera, true_pose, k):
    R, t = perturbed_pose(*true_pose, angle_deg=3.0)
    _, pts1, pts2 = correspondences(camera, *true_pose, n=50, noise_px=2.0)
    h1, h2 = to_homogeneous(pts1), to_homogeneous(pts2)
    K_inv = np.linalg.inv(camera)
    basis = tangent_basis(t)

    def sampson_at(x):
        R_, t_ = update_pose(R, t, x[:5], basis)
        F = K_inv.T @ skew(t_) @ R_ @ K_inv
        return observed_sampson(F, undistort_homogeneous(h1, camera, k + x[5]),
                                undistort_homogeneous(h2, camera, k + x[5]))[0]

    p1, p2 = undistort_homogeneous(h1, camera, k), undistort_homogeneous(h2, camera, k)
    F = K_inv.T @ skew(t) @ R @ K_inv
    J = observed_sampson_jacobian(F, fundamental_derivatives(R, t, basis, K_inv), p1, p2,
                                  observed_sampson(F, p1, p2)[1])
    step = 1e-6
    numeric = np.stack([(sampson_at(step * e) - sampson_at(-step * e)) / (2 * step)
                        for e in np.eye(6)], axis=1)
    np.testing.assert_allclose(J, numeric, rtol=1e-5, atol=1e-6 * np.abs(numeric).max())


def test_no_pull_towards_pincushion_on_noisy_distant_matches():
    # Measured in undistorted pixels, a k > 0 shrinks every distance with the image: on
    # noisy matches of distant points without distortion the fit ran to k = +0.7-1.0 and
    # the pose 22 deg away (a review). In the photos' pixels k stays near 0.
    K = np.array([[690.0, 0.0, 384.0], [0.0, 690.0, 256.0], [0.0, 0.0, 1.0]])
    R = rotation_about_axis([0.02, -0.15, 0.01], np.degrees(np.linalg.norm([0.02, -0.15, 0.01])))
    t = -R @ np.array([1.0, 0.05, 0.1])
    rng = np.random.default_rng(7)
    ks = []
    for _ in range(10):
        pixels = rng.uniform([0, 0], [768, 512], (1500, 2))
        points = (np.linalg.inv(K) @ to_homogeneous(pixels).T).T * rng.uniform(20, 60, (1500, 1))
        pts2 = project(points, K, R, t)
        inside = np.all((pts2 >= 0) & (pts2 < [768, 512]), axis=1)
        pts1 = pixels[inside] + rng.normal(0, 1.0, (inside.sum(), 2))
        pts2 = pts2[inside] + rng.normal(0, 1.0, (inside.sum(), 2))
        ks.append(fit_radial_distortion(R, t, pts1, pts2, K, "cauchy", 1.0).k)
    assert np.median(ks) < 0.15 and max(np.abs(ks)) < 0.3


@pytest.mark.parametrize("k", [-0.15, 0.0, 0.08])
def test_fit_recovers_the_distortion_and_the_pose_exactly(camera, true_pose, k):
    R, t = true_pose
    _, pts1, pts2 = correspondences(camera, R, t, n=200)
    d1, d2 = distorted_pixels(pts1, camera, k), distorted_pixels(pts2, camera, k)
    R0, t0 = refine_relative_pose(R, t, d1, d2, camera, loss="linear")  # the best it can
    fit = fit_radial_distortion(R0, t0, d1, d2, camera, loss="linear")
    assert fit.k == pytest.approx(k, abs=1e-7)
    assert pose_angle_deg(fit.R, fit.t, R, t) < 1e-5
    assert fit.sigma < 1e-6  # exact correspondences: no doubt left
    assert np.max(np.abs(fit.residuals(camera, d1, d2))) < 1e-6


def test_no_distortion_leaves_the_pose_and_no_doubt(camera, true_pose):
    # Noisy matches of a pinhole camera: k near 0 within its sigma, the pose where it was.
    _, pts1, pts2 = correspondences(camera, *true_pose, n=300, noise_px=0.3, seed=3)
    geometry = reconstruct_from_matches(pts1, pts2, camera, image_size=(640, 480))
    assert geometry.trusted, geometry.warnings
    assert abs(geometry.distortion_k) < 0.02
    assert geometry.distortion_pose_shift_deg < 0.2


def _fit(apart_deg, k, sigma):
    """A DistortionFit whose pose lies ``apart_deg`` from the identity pose below."""
    return DistortionFit(k, sigma, rotation_about_axis([0, 1, 0], apart_deg), np.array([1.0, 0, 0]))


@pytest.mark.parametrize("apart, k, sigma, doubted", [
    (4.5, -0.05, 0.001, True),   # determined, and the pose moves beyond twice the limit
    (3.5, -0.05, 0.001, False),  # within twice the 2 deg limit
    (4.5, -0.05, 0.02, False),   # a distortion the matches do not call for (2.5 sigma)
])
def test_distortion_warning_needs_a_determined_distortion_that_moves_the_pose(
        camera, apart, k, sigma, doubted):
    warning = distortion_warning(np.eye(3), np.array([1.0, 0, 0]), _fit(apart, k, sigma), camera,
                                 np.array([0.0, 0.0]), "the image's corners", TwoViewSettings())
    assert (warning is not None) == doubted
    if doubted:
        assert "barrel" in warning and "calibrate.py" in warning and f"{apart:.1f} deg" in warning


@pytest.mark.parametrize("k1", [0.0, -0.1])
def test_castle_pair_with_a_distortion_left_out_is_flagged(castle, k1):
    # castle-P19 0-1, both photos as a lens with k1 = -0.1 would take them, the true
    # distortion-free K given: every other check trusted it 9.6 deg off (docs/trust.md).
    cams = [read_strecha_camera(castle / "gt_dense_cameras" / f"{i:04d}.jpg.camera")
            for i in (0, 1)]
    images = []
    for i, cam in enumerate(cams):
        native = lens_photo(cv2.imread(str(castle / "images" / f"{i:04d}.jpg")), cam.K, k1)
        img, _, levels = load_working_image(native, cam.K, cam.dist, 768)
        images.append(img)
    K = scale_intrinsics_halved(cams[0].K, levels)
    result = reconstruct_two_view(images[0], find_matches(*images), K, img2=images[1])
    e = relative_pose_error(result.R, result.t, *relative_pose(*cams))
    error = max(e.rotation_deg, e.translation_deg)
    if k1 == 0.0:
        assert result.trusted and error < 0.5
        assert result.distortion_pose_shift_deg < 2.0
    else:
        assert error > 5.0  # what the check is for: a pose far off ...
        assert not result.trusted  # ... is no longer trusted, and the warning says why
        assert any("lens distortion" in w and "calibrate.py" in w for w in result.warnings)
        assert result.distortion_k < 0 and result.distortion_pose_shift_deg > 4.0


def test_the_check_can_be_turned_off_and_self_calibration_does_not_run_it(camera, true_pose):
    _, pts1, pts2 = correspondences(camera, *true_pose, n=300, noise_px=0.3, seed=3)
    off = reconstruct_from_matches(pts1, pts2, camera, TwoViewSettings(check_distortion=False))
    assert np.isnan(off.distortion_k) and np.isnan(off.distortion_pose_shift_deg)
    calibration = self_calibrate_pair(pts1, pts2, camera, 0.2, "prior")
    assert np.isnan(calibration.geometry.distortion_k)
    with pytest.raises(ValueError, match="check_distortion"):
        TwoViewSettings(check_distortion="yes")
