import numpy as np
import pytest

from scene3D.bundle_two_view import bundle_adjust_two_view
from scene3D.epipolar import fundamental_from_essential
from scene3D.evaluation import relative_pose_error
from scene3D.focal_fit import _focal_fundamental_derivatives, _scaled_fundamental, fit_focal_scale
from scene3D.geometry import project, rotation_about_axis, skew, to_homogeneous
from scene3D.refinement import (
    _fundamental_derivatives,
    _robust_cost,
    _sampson,
    _sampson_jacobian,
    _update_pose,
    pose_intrinsics_sensitivity,
    refine_relative_pose,
)
from scene3D.triangulation import reprojection_errors, triangulate_points
from scene3D.twoview import TwoViewSettings, reconstruct_from_matches
from scene3D.uncertainty import rotation_vector, tangent_basis

from .helpers import correspondences, scipy_bundle_adjust


def _perturbed(R, t, angle_deg=1.0):
    R0 = rotation_about_axis([0.3, -0.2, 1.0], angle_deg) @ R
    t0 = t / np.linalg.norm(t) + np.array([0.02, -0.03, 0.01])
    return R0, t0 / np.linalg.norm(t0)


def test_sampson_refinement_converges_to_the_exact_pose(camera, true_pose):
    R, t = true_pose
    _, pts1, pts2 = correspondences(camera, R, t, n=100)
    R0, t0 = _perturbed(R, t)
    R1, t1 = refine_relative_pose(R0, t0, pts1, pts2, camera, loss="linear")
    err = relative_pose_error(R1, t1, R, t)
    assert err.rotation_deg < 1e-6 and err.translation_deg < 1e-6
    assert np.linalg.norm(t1) == pytest.approx(1.0)


def test_sampson_jacobian_matches_finite_differences(camera, true_pose):
    R, t = _perturbed(*true_pose, angle_deg=3.0)
    _, pts1, pts2 = correspondences(camera, *true_pose, n=50, noise_px=2.0)
    h1, h2 = to_homogeneous(pts1), to_homogeneous(pts2)
    K_inv = np.linalg.inv(camera)

    def sampson_at(R_, t_):
        return _sampson(K_inv.T @ skew(t_) @ R_ @ K_inv, h1, h2)

    basis = tangent_basis(t)
    J = _sampson_jacobian(K_inv.T @ skew(t) @ R @ K_inv,
                          _fundamental_derivatives(R, t, basis, K_inv), h1, h2)
    step = 1e-6
    numeric = np.stack([(sampson_at(*_update_pose(R, t, step * e, basis))
                         - sampson_at(*_update_pose(R, t, -step * e, basis))) / (2 * step)
                        for e in np.eye(5)], axis=1)
    np.testing.assert_allclose(J, numeric, rtol=1e-5, atol=1e-6 * np.abs(numeric).max())


@pytest.mark.parametrize("loss", ["linear", "huber", "soft_l1", "cauchy"])
def test_robust_refinement_ends_at_a_minimum_of_its_cost(camera, true_pose, loss):
    R, t = true_pose
    _, pts1, pts2 = correspondences(camera, R, t, n=200, noise_px=0.5, seed=4)
    pts2[:20] += np.random.default_rng(9).normal(0, 3.0, (20, 2))  # moderate outliers
    R1, t1 = refine_relative_pose(*_perturbed(R, t), pts1, pts2, camera, loss=loss,
                                  scale_px=0.5)
    K_inv = np.linalg.inv(camera)
    h1, h2 = to_homogeneous(pts1), to_homogeneous(pts2)

    def cost(R_, t_):
        return _robust_cost(_sampson(K_inv.T @ skew(t_) @ R_ @ K_inv, h1, h2), loss, 0.5)

    basis = tangent_basis(t1)
    at_result = cost(R1, t1)
    for e in np.vstack([np.eye(5), -np.eye(5)]):
        assert cost(*_update_pose(R1, t1, 1e-4 * e, basis)) > at_result
    err = relative_pose_error(R1, t1, R, t)
    assert err.rotation_deg < 0.2 and err.translation_deg < 1.0


def test_two_view_bundle_adjustment_is_exact_without_noise(camera, true_pose):
    R, t = true_pose
    points, pts1, pts2 = correspondences(camera, R, t, n=80)
    R0, t0 = _perturbed(R, t, 0.5)
    X0 = triangulate_points(pts1, pts2, camera, R0, t0)
    R1, t1, X1 = bundle_adjust_two_view(R0, t0, X0, pts1, pts2, camera, loss="linear")
    err = relative_pose_error(R1, t1, R, t)
    assert err.rotation_deg < 1e-5 and err.translation_deg < 1e-5
    assert reprojection_errors(X1, pts1, pts2, camera, R1, t1).max() < 1e-5
    np.testing.assert_allclose(X1 * np.linalg.norm(t), points, rtol=1e-5)


@pytest.mark.parametrize("loss", ["linear", "soft_l1", "cauchy"])
def test_two_view_bundle_adjustment_reaches_a_minimum_scipy_does_not_beat(camera, true_pose,
                                                                          loss):
    """Against scipy's least_squares run to convergence, on noisy matches with outliers.
    With convex losses both reach the same optimum. Under Cauchy, scipy's clamped
    curvature correction leaves the outliers' points with singular blocks and it stops
    where it started; scene3D's solver must reach a lower cost."""
    from scene3D.bundle import Observations

    R, t = true_pose
    t = t / np.linalg.norm(t)
    _, pts1, pts2 = correspondences(camera, R, t, n=40, noise_px=0.5, seed=3)
    pts2[:4] += 6.0  # outliers
    X0 = triangulate_points(pts1, pts2, camera, R, t)

    def cost(R_, t_, X_):
        r = np.vstack([project(X_, camera, np.eye(3), np.zeros(3)) - pts1,
                       project(X_, camera, R_, t_) - pts2])
        return _robust_cost(r, loss, 0.5)

    R1, t1, X1 = bundle_adjust_two_view(R, t, X0, pts1, pts2, camera, loss=loss, scale_px=0.5)
    assert np.linalg.norm(t1) == pytest.approx(1.0)
    # A minimum: moving the pose or the points a little costs more.
    at_result = cost(R1, t1, X1)
    basis = tangent_basis(t1)
    for e in np.vstack([np.eye(5), -np.eye(5)]):
        assert cost(*_update_pose(R1, t1, 1e-5 * e, basis), X1) > at_result
    rng = np.random.default_rng(0)
    for _ in range(5):
        assert cost(R1, t1, X1 + rng.normal(0, 1e-5, X1.shape)) > at_result
    obs = Observations(np.repeat([0, 1], 40), np.tile(np.arange(40), 2),
                       np.vstack([pts1, pts2]))
    Rs, ts, Xs = scipy_bundle_adjust(np.stack([np.eye(3), R]), np.stack([np.zeros(3), t]), X0,
                                     obs, camera, fixed_view=0, loss=loss, scale_px=0.5,
                                     max_evaluations=3000)
    scale = np.linalg.norm(ts[1])  # scipy's solution keeps the scale gauge free
    theirs = cost(Rs[1], ts[1] / scale, Xs / scale)
    if loss == "cauchy":
        assert at_result < 0.8 * theirs  # measured: 10.3 against 14.5
    else:
        assert at_result == pytest.approx(theirs, rel=1e-6)
        assert relative_pose_error(R1, t1, Rs[1], ts[1]).max_deg < 0.01


def test_bundle_adjustment_does_not_worsen_noisy_pairs(camera, true_pose):
    R, t = true_pose
    plain_errors, adjusted_errors = [], []
    for seed in range(8):
        _, pts1, pts2 = correspondences(camera, R, t, n=300, noise_px=0.5, seed=seed)
        plain = reconstruct_from_matches(pts1, pts2, camera)
        adjusted = reconstruct_from_matches(pts1, pts2, camera,
                                            TwoViewSettings(bundle_adjust=True))
        plain_errors.append(relative_pose_error(plain.R, plain.t, R, t).max_deg)
        adjusted_errors.append(relative_pose_error(adjusted.R, adjusted.t, R, t).max_deg)
        assert np.linalg.norm(adjusted.t) == pytest.approx(1.0)
        # F is the epipolar geometry of the adjusted pose, not of the pose before it.
        F = fundamental_from_essential(adjusted.E, camera)
        assert min(np.abs(F - adjusted.F).max(), np.abs(F + adjusted.F).max()) < 1e-12
    assert np.mean(adjusted_errors) <= np.mean(plain_errors) + 0.005
    assert max(adjusted_errors) < 2.0


def test_bundle_adjustment_keeps_the_book_pair_near_the_truth(fountain):
    """The optional adjustment moves the pose by hundredths of a degree, not more.

    On the book pair it is 0.025 deg further from the truth than without (scene3D's
    bias-free SIFT; within 0.01 deg with OpenCV's default SIFT): both stay within 0.1 deg.
    """
    from scene3D import SceneReconstruction3D
    from scene3D.datasets import read_strecha_camera, relative_pose

    cams = [read_strecha_camera(fountain / "gt_dense_cameras" / f"000{i}.jpg.camera")
            for i in (4, 5)]
    errors = []
    for adjust in (False, True):
        scene = SceneReconstruction3D(cams[0].K, settings=TwoViewSettings(bundle_adjust=adjust))
        scene.load_image_pair(fountain / "images" / "0004.jpg", fountain / "images" / "0005.jpg")
        r = scene.reconstruct()
        errors.append(relative_pose_error(r.R, r.t, *relative_pose(*cams)).max_deg)
    assert max(errors) < 0.1
    assert abs(errors[1] - errors[0]) < 0.05


def test_focal_jacobian_matches_finite_differences(camera, true_pose):
    R, t = _perturbed(*true_pose, angle_deg=3.0)
    _, pts1, pts2 = correspondences(camera, *true_pose, n=50, noise_px=2.0)
    h1, h2 = to_homogeneous(pts1), to_homogeneous(pts2)
    K_inv, log_s = np.linalg.inv(camera), 0.2

    def sampson_at(x):
        R_, t_ = _update_pose(R, t, x[:5], basis)
        return _sampson(_scaled_fundamental(R_, t_, log_s + x[5], K_inv), h1, h2)

    basis = tangent_basis(t)
    J = _sampson_jacobian(_scaled_fundamental(R, t, log_s, K_inv),
                          _focal_fundamental_derivatives(R, t, log_s, basis, K_inv), h1, h2)
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


def test_the_pose_moves_with_the_intrinsics_as_refits_show():
    """pose_intrinsics_sensitivity against refinements under a perturbed K (log f, c_x, c_y)."""
    K = np.array([[780.0, 0.0, 331.0], [0.0, 780.0, 228.0], [0.0, 0.0, 1.0]])
    R = rotation_about_axis([0.25, 1.0, 0.12], 10.0)
    t = np.array([-0.9, 0.1, 0.3])
    t /= np.linalg.norm(t)
    _, pts1, pts2 = correspondences(K, R, t, 300, 0.5, 1)
    R0, t0 = refine_relative_pose(R, t, pts1, pts2, K, "cauchy", 0.5, 100)
    S = pose_intrinsics_sensitivity(R0, t0, pts1, pts2, K, "cauchy", 0.5)
    assert S.shape == (5, 3)
    basis = tangent_basis(t0)
    for j, h in enumerate([1e-3, 0.5, 0.5]):
        K_moved = K.copy()
        if j == 0:
            K_moved[:2, :2] *= np.exp(h)
        else:
            K_moved[j - 1, 2] += h
        R1, t1 = refine_relative_pose(R0, t0, pts1, pts2, K_moved, "cauchy", 0.5, 100)
        moved = np.concatenate([rotation_vector(R1 @ R0.T), basis @ (t1 - t0)]) / h
        np.testing.assert_allclose(S[:, j], moved, rtol=0.03, atol=2e-3 * np.abs(S[:, j]).max())
