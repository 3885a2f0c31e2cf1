import numpy as np
import pytest

from scene3D.focal_fit import _focal_fundamental_derivatives, _scaled_fundamental, fit_focal_scale
from scene3D.geometry import to_homogeneous
from scene3D.refinement import _sampson, _sampson_jacobian, _update_pose, refine_relative_pose
from scene3D.uncertainty import tangent_basis

from .helpers import correspondences, perturbed_pose


def test_focal_jacobian_matches_finite_differences(camera, true_pose):
    R, t = perturbed_pose(*true_pose, angle_deg=3.0)
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
