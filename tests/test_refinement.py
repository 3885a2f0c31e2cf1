import numpy as np
import pytest

from scene3D.evaluation import relative_pose_error
from scene3D.geometry import rotation_about_axis
from scene3D.refinement import bundle_adjust_two_view, refine_relative_pose
from scene3D.triangulation import reprojection_errors, triangulate_points
from scene3D.twoview import TwoViewSettings, reconstruct_from_matches

from .helpers import correspondences


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
    assert np.mean(adjusted_errors) <= np.mean(plain_errors) + 0.005
    assert max(adjusted_errors) < 2.0


def test_bundle_adjustment_does_not_worsen_the_book_pair(fountain):
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
    assert errors[1] <= errors[0] + 0.01
