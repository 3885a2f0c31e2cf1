import numpy as np
import pytest

from scene3D.evaluation import relative_pose_error
from scene3D.geometry import rotation_about_axis, skew, to_homogeneous
from scene3D.geometry.epipolar import (
    fundamental_derivatives,
    sampson_jacobian,
    sampson_residuals_homogeneous,
)
from scene3D.optim.least_squares import robust_cost
from scene3D.optim.refinement import pose_intrinsics_sensitivity, refine_relative_pose
from scene3D.optim.uncertainty import rotation_vector, tangent_basis, update_pose

from .helpers import correspondences, perturbed_pose


def test_sampson_refinement_converges_to_the_exact_pose(camera, true_pose):
    R, t = true_pose
    _, pts1, pts2 = correspondences(camera, R, t, n=100)
    R0, t0 = perturbed_pose(R, t)
    R1, t1 = refine_relative_pose(R0, t0, pts1, pts2, camera, loss="linear")
    err = relative_pose_error(R1, t1, R, t)
    assert err.rotation_deg < 1e-6 and err.translation_deg < 1e-6
    assert np.linalg.norm(t1) == pytest.approx(1.0)


def test_sampson_jacobian_matches_finite_differences(camera, true_pose):
    R, t = perturbed_pose(*true_pose, angle_deg=3.0)
    _, pts1, pts2 = correspondences(camera, *true_pose, n=50, noise_px=2.0)
    h1, h2 = to_homogeneous(pts1), to_homogeneous(pts2)
    K_inv = np.linalg.inv(camera)

    def sampson_at(R_, t_):
        return sampson_residuals_homogeneous(K_inv.T @ skew(t_) @ R_ @ K_inv, h1, h2)

    basis = tangent_basis(t)
    J = sampson_jacobian(K_inv.T @ skew(t) @ R @ K_inv,
                         fundamental_derivatives(R, t, basis, K_inv), h1, h2)
    step = 1e-6
    numeric = np.stack([(sampson_at(*update_pose(R, t, step * e, basis))
                         - sampson_at(*update_pose(R, t, -step * e, basis))) / (2 * step)
                        for e in np.eye(5)], axis=1)
    np.testing.assert_allclose(J, numeric, rtol=1e-5, atol=1e-6 * np.abs(numeric).max())


@pytest.mark.parametrize("loss", ["linear", "huber", "soft_l1", "cauchy"])
def test_robust_refinement_ends_at_a_minimum_of_its_cost(camera, true_pose, loss):
    R, t = true_pose
    _, pts1, pts2 = correspondences(camera, R, t, n=200, noise_px=0.5, seed=4)
    pts2[:20] += np.random.default_rng(9).normal(0, 3.0, (20, 2))  # moderate outliers
    R1, t1 = refine_relative_pose(*perturbed_pose(R, t), pts1, pts2, camera, loss=loss,
                                  scale_px=0.5)
    K_inv = np.linalg.inv(camera)
    h1, h2 = to_homogeneous(pts1), to_homogeneous(pts2)

    def cost(R_, t_):
        F = K_inv.T @ skew(t_) @ R_ @ K_inv
        return robust_cost(sampson_residuals_homogeneous(F, h1, h2), loss, 0.5)

    basis = tangent_basis(t1)
    at_result = cost(R1, t1)
    for e in np.vstack([np.eye(5), -np.eye(5)]):
        assert cost(*update_pose(R1, t1, 1e-4 * e, basis)) > at_result
    err = relative_pose_error(R1, t1, R, t)
    assert err.rotation_deg < 0.2 and err.translation_deg < 1.0


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
