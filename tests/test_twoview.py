import numpy as np
import pytest

from scene3D.epipolar import estimate_homography
from scene3D.errors import ReconstructionError
from scene3D.evaluation import relative_pose_error
from scene3D.features import find_matches
from scene3D.geometry import project
from scene3D.synthetic import random_points
from scene3D.twoview import (
    TwoViewSettings,
    off_plane_evidence,
    plane_poses,
    reconstruct_from_matches,
    reconstruct_two_view,
)

from .helpers import correspondences


def test_noise_free_pose_and_points_are_exact(camera, true_pose):
    R, t = true_pose
    points, pts1, pts2 = correspondences(camera, R, t, n=300)
    r = reconstruct_from_matches(pts1, pts2, camera)
    err = relative_pose_error(r.R, r.t, R, t)
    assert err.rotation_deg < 1e-6 and err.translation_deg < 1e-6
    assert np.linalg.norm(r.t) == pytest.approx(1.0)
    assert r.reprojection_rmse_px < 1e-6
    # Same points, in units of the baseline.
    scale = np.linalg.norm(t)
    expected = {tuple(np.round(p, 6)) for p in pts1}
    assert {tuple(np.round(p, 6)) for p in r.pts1} <= expected
    reproj = project(r.points3d * scale, camera, R, t)
    np.testing.assert_allclose(reproj, r.pts2, atol=1e-6)
    assert r.num_inliers == 300 and r.trusted


@pytest.mark.parametrize("seed", [0, 1, 2, 3])
def test_noisy_pose_is_within_bounds(camera, true_pose, seed):
    R, t = true_pose
    _, pts1, pts2 = correspondences(camera, R, t, n=300, noise_px=0.5, seed=seed)
    r = reconstruct_from_matches(pts1, pts2, camera)
    err = relative_pose_error(r.R, r.t, R, t)
    assert err.rotation_deg < 0.5
    assert err.translation_deg < 2.0
    assert 0.2 < r.reprojection_rmse_px < 1.0


def test_too_few_matches(camera, true_pose):
    R, t = true_pose
    _, pts1, pts2 = correspondences(camera, R, t, n=12)
    with pytest.raises(ReconstructionError, match="too few matches") as info:
        reconstruct_from_matches(pts1, pts2, camera)
    assert info.value.reason == "too_few_matches"
    assert info.value.counts == {"matches": 12, "required": 20}


def test_pure_rotation_points_are_refused(camera, true_pose):
    R, _ = true_pose
    _, pts1, pts2 = correspondences(camera, R, np.zeros(3), n=300, noise_px=0.3)
    with pytest.raises(ReconstructionError) as info:
        reconstruct_from_matches(pts1, pts2, camera)
    assert info.value.reason == "no_parallax"


def test_tiny_baseline_is_refused(camera, true_pose):
    R, t = true_pose
    _, pts1, pts2 = correspondences(camera, R, 0.01 * t, n=300, noise_px=0.3)
    with pytest.raises(ReconstructionError) as info:
        reconstruct_from_matches(pts1, pts2, camera)
    assert info.value.reason == "no_parallax"


def test_random_matches_are_refused(camera):
    rng = np.random.default_rng(3)
    pts1 = rng.uniform(0, 640, (200, 2))
    pts2 = rng.uniform(0, 640, (200, 2))
    with pytest.raises(ReconstructionError):
        reconstruct_from_matches(pts1, pts2, camera, TwoViewSettings(min_inliers=30))


def test_planar_scene_is_refused(camera, true_pose):
    """All points on one plane: the pose is ambiguous, so the pair is refused."""
    R, t = true_pose
    rng = np.random.default_rng(0)
    xy = rng.uniform(-3, 3, (300, 2))
    points = np.column_stack([xy, 7.0 + 0.2 * xy[:, 0]])
    pts1 = project(points, camera, np.eye(3), np.zeros(3))
    pts2 = project(points, camera, R, t)
    with pytest.raises(ReconstructionError, match="planar") as info:
        reconstruct_from_matches(pts1, pts2, camera)
    assert info.value.reason == "planar_scene"


def _plane_and_points(camera, R, t, n_plane, n_off, noise_px, seed=0):
    """``n_plane`` points on one plane and ``n_off`` spread in depth, seen from both views."""
    rng = np.random.default_rng(seed)
    xy = rng.uniform(-3, 3, (n_plane, 2))
    points = np.vstack([np.column_stack([xy, 7.0 + 0.2 * xy[:, 0]]),
                        random_points(n_off, seed + 1).reshape(-1, 3)])
    pts1 = project(points, camera, np.eye(3), np.zeros(3))
    pts2 = project(points, camera, R, t)
    return (pts1 + rng.normal(0, noise_px, pts1.shape),
            pts2 + rng.normal(0, noise_px, pts2.shape))


def test_a_dominant_plane_with_depth_off_it_is_kept_but_untrusted(camera, true_pose):
    """96 % of the matches on one plane, 16 spread in depth: the pose is not ambiguous."""
    R, t = true_pose
    pts1, pts2 = _plane_and_points(camera, R, t, 400, 16, noise_px=0.2)
    result = reconstruct_from_matches(pts1, pts2, camera)
    assert result.homography_inlier_ratio > TwoViewSettings().planar_ratio
    err = relative_pose_error(result.R, result.t, R, t)
    assert max(err.rotation_deg, err.translation_deg) < 0.5
    assert not result.trusted and any("homography" in w for w in result.warnings)


def test_plane_poses_are_two_and_one_is_the_truth(camera, true_pose):
    R, t = true_pose
    pts1, pts2 = _plane_and_points(camera, R, t, 300, 0, noise_px=0.0)
    H, _ = estimate_homography(pts1, pts2)
    poses = plane_poses(H, camera, pts1, pts2)
    assert len(poses) == 2
    errors = [relative_pose_error(R_p, t_p, R, t) for R_p, t_p in poses]
    assert min(e.rotation_deg + e.translation_deg for e in errors) < 1e-4


@pytest.mark.parametrize("seed", [0, 1])
def test_matches_off_a_dominant_plane_get_their_vote(camera, true_pose, seed):
    """12 of 312 matches off the plane: whatever model USAC's plane-bound samples give,
    the plane's own poses refined on all matches recover the true one."""
    R, t = true_pose
    pts1, pts2 = _plane_and_points(camera, R, t, 300, 12, noise_px=0.3, seed=seed)
    result = reconstruct_from_matches(pts1, pts2, camera)
    err = relative_pose_error(result.R, result.t, R, t)
    assert max(err.rotation_deg, err.translation_deg) < 0.5
    assert result.num_inliers >= 310 and not result.trusted


def test_off_plane_evidence_counts_the_matches_that_settle_the_ambiguity(camera, true_pose):
    R, t = true_pose
    pts1, pts2 = _plane_and_points(camera, R, t, 300, 12, noise_px=0.0)
    H, on_plane = estimate_homography(pts1, pts2)
    assert on_plane[:300].all() and not on_plane[300:].any()
    # Most of the 12 points off the plane rule the other pose out (one may happen to
    # lie near its epipolar lines too).
    assert 10 <= off_plane_evidence(H, camera, R, t, pts1, pts2, on_plane, 1.0) <= 12
    flat1, flat2 = pts1[:300], pts2[:300]
    assert off_plane_evidence(H, camera, R, t, flat1, flat2, on_plane[:300], 1.0) == 0
    few1, few2 = _plane_and_points(camera, R, t, 300, 3, noise_px=0.0)
    with pytest.raises(ReconstructionError, match="planar") as info:
        reconstruct_from_matches(few1, few2, camera)
    assert info.value.counts["off_plane_evidence"] < 10


def test_rendered_pair_end_to_end(rendered_pair):
    img1, img2, K, R, t = rendered_pair
    result = reconstruct_two_view(img1, find_matches(img1, img2, "SIFT"), K)
    err = relative_pose_error(result.R, result.t, R, t)
    assert err.rotation_deg < 0.1 and err.translation_deg < 0.5
    assert result.num_points > 500
    assert result.colors.shape == (result.num_points, 3) and result.colors.dtype == np.uint8
    assert result.trusted
    assert result.Rt2.shape == (3, 4)
    assert {"features", "matching", "geometry", "total"} <= set(result.timings_s)


def test_rendered_pure_rotation_raises(rotated_pair):
    img1, img2, K = rotated_pair
    with pytest.raises(ReconstructionError) as info:
        reconstruct_two_view(img1, find_matches(img1, img2, "SIFT"), K)
    assert info.value.reason == "no_parallax"


def test_weak_pairs_are_marked_untrusted(camera, true_pose):
    """Few inliers among many outliers: a pose comes back, flagged with the reasons."""
    R, t = true_pose
    _, pts1, pts2 = correspondences(camera, R, t, n=40, noise_px=0.3)
    rng = np.random.default_rng(1)
    outliers1 = rng.uniform(0, 640, (160, 2))
    outliers2 = rng.uniform(0, 640, (160, 2))
    r = reconstruct_from_matches(np.vstack([pts1, outliers1]), np.vstack([pts2, outliers2]),
                                 camera)
    assert not r.trusted
    text = " ".join(r.warnings)
    assert "inliers" in text and "of the 200 matches" in text


def test_short_baseline_is_marked_untrusted(camera, true_pose):
    R, t = true_pose
    _, pts1, pts2 = correspondences(camera, R, 0.15 * t, n=300, noise_px=0.1)
    r = reconstruct_from_matches(pts1, pts2, camera)
    assert 1.0 <= r.median_parallax_deg < 2.0
    assert not r.trusted and "weak parallax" in " ".join(r.warnings)


@pytest.mark.parametrize("factor", [0.6, 1.6])
def test_a_calibration_for_another_focal_length_is_flagged(camera, true_pose, factor):
    """Photos from `camera`, calibration with its focal lengths times `factor`."""
    R, t = true_pose
    _, pts1, pts2 = correspondences(camera, R, t, n=300, noise_px=0.3)
    wrong = camera.copy()
    wrong[:2, :2] *= factor
    r = reconstruct_from_matches(pts1, pts2, wrong)
    assert r.focal_scale == pytest.approx(1.0 / factor, rel=0.03)
    assert not r.trusted and "focal length" in " ".join(r.warnings)
    right = reconstruct_from_matches(pts1, pts2, camera)
    assert right.focal_scale == pytest.approx(1.0, abs=0.03) and right.trusted
    assert right.focal_scale_sigma < 0.02


def test_a_near_miss_of_the_focal_length_is_not_flagged(camera, true_pose):
    # 10 % off: within TwoViewSettings.max_focal_mismatch, reported but trusted.
    R, t = true_pose
    _, pts1, pts2 = correspondences(camera, R, t, n=300, noise_px=0.3)
    near = camera.copy()
    near[:2, :2] *= 1.1
    r = reconstruct_from_matches(pts1, pts2, near)
    assert r.focal_scale == pytest.approx(1 / 1.1, rel=0.03) and r.trusted
