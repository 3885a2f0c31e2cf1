import numpy as np
import pytest

from scene3D.evaluation import relative_pose_error
from scene3D.geometry import project
from scene3D.geometry.epipolar import fundamental_from_essential
from scene3D.geometry.triangulation import reprojection_errors, triangulate_points
from scene3D.optim.bundle_two_view import bundle_adjust_two_view
from scene3D.optim.least_squares import robust_cost
from scene3D.optim.uncertainty import tangent_basis, update_pose
from scene3D.twoview import TwoViewSettings, reconstruct_from_matches

from .helpers import correspondences, perturbed_pose, scipy_bundle_adjust


def test_two_view_bundle_adjustment_is_exact_without_noise(camera, true_pose):
    R, t = true_pose
    points, pts1, pts2 = correspondences(camera, R, t, n=80)
    R0, t0 = perturbed_pose(R, t, 0.5)
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
    from scene3D.optim.bundle import Observations

    R, t = true_pose
    t = t / np.linalg.norm(t)
    _, pts1, pts2 = correspondences(camera, R, t, n=40, noise_px=0.5, seed=3)
    pts2[:4] += 6.0  # outliers
    X0 = triangulate_points(pts1, pts2, camera, R, t)

    def cost(R_, t_, X_):
        r = np.vstack([project(X_, camera, np.eye(3), np.zeros(3)) - pts1,
                       project(X_, camera, R_, t_) - pts2])
        return robust_cost(r, loss, 0.5)

    R1, t1, X1 = bundle_adjust_two_view(R, t, X0, pts1, pts2, camera, loss=loss, scale_px=0.5)
    assert np.linalg.norm(t1) == pytest.approx(1.0)
    # A minimum: moving the pose or the points a little costs more.
    at_result = cost(R1, t1, X1)
    basis = tangent_basis(t1)
    for e in np.vstack([np.eye(5), -np.eye(5)]):
        assert cost(*update_pose(R1, t1, 1e-5 * e, basis), X1) > at_result
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
    from scene3D.io.datasets import read_strecha_camera, relative_pose

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
