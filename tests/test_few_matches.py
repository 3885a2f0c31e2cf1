"""Real pairs cut down to few matches (a narrow view, a few textured spots): whatever comes
back must not be a wrong pose marked trusted. The cases are the worst of a sweep over
the three shared scenes (crops of 15-30 % of the image, random subsets of 50-150
matches, 192-384 px images; docs/trust.md, "Few matches")."""

import dataclasses

import numpy as np

from scene3D.evaluation import relative_pose_error
from scene3D.twoview import reconstruct_two_view

from .helpers import strecha_pair


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
