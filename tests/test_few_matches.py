"""Real pairs with few matches (a narrow view, a few textured spots, a chessboard on a
wall): whatever comes back must not be a wrong pose marked trusted. The cases come from
sweeps over the three shared scenes cut down (benchmarks/few_matches.py) and over the
chessboard sets (benchmarks/chessboard_pairs.py); docs/trust.md, "Few matches"."""

import dataclasses

import cv2
import numpy as np
import pytest

from scene3D.calibration import BoardSpec, calibrate
from scene3D.errors import ReconstructionError
from scene3D.evaluation import relative_pose_error
from scene3D.geometry import relative_pose
from scene3D.scene import SceneReconstruction3D
from scene3D.twoview import TwoViewSettings, reconstruct_two_view

from .helpers import detect_folder, strecha_pair


def _pair(folder, a, b, max_width):
    scene, truth = strecha_pair(folder, a, b, max_width)
    return scene, scene.matches("SIFT"), truth


def _reconstruct(scene, matches, keep):
    kept = dataclasses.replace(matches, pts1=matches.pts1[keep], pts2=matches.pts2[keep])
    return reconstruct_two_view(scene.img1, kept, scene.K)


def test_a_far_rival_flags_a_confirmed_pose_on_a_nearly_planar_strip(herz_jesus):
    """Herz-Jesus-P8 5-6 at 384 px, the matches in the top 30 % of image 1 (the facade's
    upper storey: a homography explains 98 % of them): the restarts reach the best pose
    twice, 8 deg off, and once a pose 11 deg from it; trusted before rivals of a
    confirmed fit counted."""
    scene, matches, truth = _pair(herz_jesus, 5, 6, 384)
    result = _reconstruct(scene, matches, matches.pts1[:, 1] <= 0.3 * scene.img1.shape[0])
    assert relative_pose_error(result.R, result.t, *truth).max_deg > 5
    assert not result.trusted
    assert any(w.startswith("another pose") for w in result.warnings)


def test_a_far_rival_flags_a_confirmed_pose_from_a_hundred_matches(castle):
    """castle-P19 7-9 at 768 px, 100 of its 310 matches drawn at random: 59 inliers, most on
    one wall; the best pose is 31 deg off in translation direction, and a rival 33 deg
    from it lies 5 deg from the truth."""
    scene, matches, truth = _pair(castle, 7, 9, 768)
    keep = np.sort(np.random.default_rng(10_100).choice(len(matches.pts1), 100, replace=False))
    result = _reconstruct(scene, matches, keep)
    assert relative_pose_error(result.R, result.t, *truth).max_deg > 5
    assert not result.trusted


@pytest.fixture(scope="module")
def wall_board(chessboards):
    """Udacity's car camera (1280x720; its two 1281x721 views left out), calibrated from its
    own chessboard photos, and each view's board pose (board-to-camera ``R, t``)."""
    folder = chessboards / "udacity-lane-9x6"
    views = [d for d in detect_folder(folder, BoardSpec())
             if d.name not in ("calibration7.jpg", "calibration15.jpg")]
    result = calibrate(views, (1280, 720), BoardSpec())
    poses = {name: (cv2.Rodrigues(r)[0], t)
             for name, r, t in zip(result.per_view_errors_px, result.rvecs, result.tvecs)}
    return folder, result, poses


def _wall_pair(wall_board, a, b):
    folder, calibration, poses = wall_board
    scene = SceneReconstruction3D(calibration.K, calibration.dist)
    scene.load_image_pair(folder / f"calibration{a}.jpg", folder / f"calibration{b}.jpg",
                          max_width=None)
    return scene, relative_pose(*poses[f"calibration{a}.jpg"], *poses[f"calibration{b}.jpg"])


def test_a_chessboard_on_a_plain_wall_with_too_few_distinct_matches_is_refused(wall_board):
    """A printed chessboard on a plain wall, views 12 and 18: SIFT lists 30 matches, 20 of
    them distinct; the best essential matrix has 15 inliers as listed, 6 distinct points,
    which a pose of 5 degrees of freedom nearly interpolates. Counted as listed, they
    gave a pose 153 deg off with sigmas of 0.0003 deg, flagged only because 15 is below
    50; counted once, too few agree."""
    scene, _ = _wall_pair(wall_board, 12, 18)
    with pytest.raises(ReconstructionError) as info:
        scene.reconstruct("SIFT")
    assert info.value.reason == "too_few_inliers"
    assert info.value.counts["inliers"] < TwoViewSettings().min_inliers


def test_a_wrong_pose_on_a_chessboard_wall_counts_its_inliers_once(wall_board):
    """Views 11 and 19 of the wall: 18 distinct inliers, listed 27 times, agree on a pose
    76 deg off, with sigmas of 0.1-0.3 deg. What flags it is the floor on the inliers,
    which counts each correspondence once."""
    scene, truth = _wall_pair(wall_board, 11, 19)
    result = scene.reconstruct("SIFT")
    assert relative_pose_error(result.R, result.t, *truth).max_deg > 5
    assert not result.trusted
    distinct = np.unique(np.hstack([result.inlier_pts1, result.inlier_pts2]), axis=0)
    assert result.num_inliers == len(distinct) < TwoViewSettings().trusted_inliers
    assert result.warnings[0].startswith(f"only {result.num_inliers} inliers")
