"""Real data with ground truth: castle-P19's rows of identical windows."""

import pytest

from scene3D.evaluation import relative_pose_error
from scene3D.geometry.pose import choose_pose
from scene3D.optim.uncertainty import CHI2_99_POSE
from scene3D.twoview import TwoViewSettings, essential_fit
from scene3D.twoview.essential_fit import fit_essential

from .helpers import strecha_pair


@pytest.mark.parametrize("pair", [(13, 14), (12, 14)])
def test_mismatched_windows_do_not_pull_the_pose(castle, pair):
    """Matches between neighbouring windows fit a pose 1.6 deg (13-14) or 4 deg (12-14)
    off the truth within 1 px, together with the right matches fitted a little
    worse; a single MAGSAC++ start at 1 px takes it. Compared at the noise of the
    keypoints (scene3D.twoview.essential_fit.fit_essential) the true pose wins.
    """
    scene, truth = strecha_pair(castle, *pair, 1536)
    result = scene.reconstruct("SIFT")
    assert relative_pose_error(result.R, result.t, *truth).max_deg < 0.5
    matches = scene.matches("SIFT")
    single = fit_essential(matches.pts1, matches.pts2, scene.K, max_starts=1)
    R, t, _, _ = choose_pose(single.E, matches.pts1[single.inliers],
                             matches.pts2[single.inliers], scene.K)
    assert relative_pose_error(R, t, *truth).max_deg > 1.0


def test_restarts_that_disagree_within_the_covariance_are_no_verdict(castle):
    """Pair 2-4 at 768 px: eight restarts never meet twice, their optima up to 0.7 deg
    apart, but every one lies within the pose's covariance (translation direction
    +-0.44 deg): the sigmas already say it. The pose is 0.2 deg off: trusted."""
    scene, truth = strecha_pair(castle, 2, 4, 768)
    result = scene.reconstruct("SIFT")
    assert relative_pose_error(result.R, result.t, *truth).max_deg < 0.5
    assert result.robust_spread_deg > 0.5
    assert result.trusted, result.warnings


def test_restarts_that_disagree_beyond_the_covariance_flag_the_pose(castle):
    """Pair 15-17 at 1536 px: mismatched windows hold a pose 3 deg off. In eight starts
    the restarts never meet twice and end 0.7 deg apart, far outside its covariance
    (+-0.07 deg): flagged for them. With the default sixteen the best is met twice (the
    rival, 0.7 deg away, lies within the purpose's 2 deg: no verdict), and the dense
    flow flags the pose instead."""
    scene, truth = strecha_pair(castle, 15, 17, 1536)
    scene.settings = TwoViewSettings(max_starts=8)
    result = scene.reconstruct("SIFT")
    assert relative_pose_error(result.R, result.t, *truth).max_deg > 2.0
    assert not result.trusted and result.robust_starts == 8
    assert any("robust starts" in w for w in result.warnings)
    scene, _ = strecha_pair(castle, 15, 17, 1536)
    result = scene.reconstruct("SIFT")
    assert not result.trusted and result.robust_starts < 16
    assert [w for w in result.warnings if "dense optical flow" in w], result.warnings


def test_the_refinement_at_the_threshold_may_not_leave_the_fit_at_the_noise(castle,
                                                                            monkeypatch):
    """Pair 8-9 at 768 px: the restarts, compared at the noise (0.42 px), find a pose
    0.3 deg off; refined again at the 1 px threshold, the matches between the two pull
    it 2.2 deg off. That shift lies far outside the covariance of the fit at the
    noise, so that fit is kept (scene3D.twoview.essential_fit.widening_shift_chi2)."""
    scene, truth = strecha_pair(castle, 8, 9, 768)
    result = scene.reconstruct("SIFT")
    assert relative_pose_error(result.R, result.t, *truth).max_deg < 0.5
    matches = scene.matches("SIFT")
    fit = fit_essential(matches.pts1, matches.pts2, scene.K)
    assert fit.widening_shift_chi2 > CHI2_99_POSE
    assert fit.fitted_threshold_px == fit.comparison_threshold_px < 0.5
    monkeypatch.setattr(essential_fit, "CHI2_99_POSE", float("inf"))  # as before
    wide = fit_essential(matches.pts1, matches.pts2, scene.K)
    R, t, _, _ = choose_pose(wide.E, matches.pts1[wide.inliers], matches.pts2[wide.inliers],
                             scene.K)
    assert relative_pose_error(R, t, *truth).max_deg > 2.0


def test_a_pose_whose_inliers_lie_behind_the_cameras_is_flagged(castle):
    """Pair 12-16 at 1536 px (four views apart across the courtyard): 79 of the matches
    agree on a pose 87-91 deg off with sigmas of 0.14 / 0.41 deg, and no other check
    doubts it; 37 % of those inliers triangulate behind a camera."""
    scene, truth = strecha_pair(castle, 12, 16, 1536)
    result = scene.reconstruct("SIFT")
    assert relative_pose_error(result.R, result.t, *truth).max_deg > 45
    assert result.behind_share > 0.3
    assert not result.trusted
    assert any("behind a camera" in w for w in result.warnings)


def test_right_poses_have_few_inliers_behind_the_cameras(castle):
    """Pairs 4-6 and 4-7 at 768 px, right poses (< 1 deg) with the most inliers behind
    a camera of the Strecha scenes' gaps 1-5 (0.04 with SIFT; 4-7 with ORB 0.11)."""
    for pair in [(4, 6), (4, 7)]:
        scene, truth = strecha_pair(castle, *pair, 768)
        result = scene.reconstruct("SIFT")
        assert relative_pose_error(result.R, result.t, *truth).max_deg < 1
        assert result.behind_share < 0.06  # the limit is 0.2
        assert not any("behind a camera" in w for w in result.warnings)


def test_max_behind_share_is_a_share():
    with pytest.raises(ValueError, match="max_behind_share"):
        TwoViewSettings(max_behind_share=1.5)


def test_more_restarts_confirm_a_right_pose_that_eight_left_in_doubt(castle):
    """Pair 10-12 at 768 px: in eight starts the best pose is not met twice and a rival
    1.3 deg away, outside its covariance, costs about as much: flagged, though the pose
    is 0.4 deg from the truth. The default sixteen meet the best twice (the rival then
    lies within the purpose's 2 deg): the same pose, trusted."""
    scene, truth = strecha_pair(castle, 10, 12, 768)
    scene.settings = TwoViewSettings(max_starts=8)
    doubted = scene.reconstruct("SIFT")
    assert not doubted.trusted and doubted.robust_starts == 8
    assert any("robust starts" in w for w in doubted.warnings)
    scene, _ = strecha_pair(castle, 10, 12, 768)
    result = scene.reconstruct("SIFT")
    assert result.trusted and 8 < result.robust_starts < 16, result.warnings
    assert relative_pose_error(result.R, result.t, *truth).max_deg < 0.6
