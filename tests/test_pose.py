import numpy as np
import pytest

from scene3D.errors import ReconstructionError
from scene3D.geometry import project
from scene3D.geometry.epipolar import essential_from_pose
from scene3D.geometry.pose import choose_pose, decompose_essential


def test_four_candidates_are_proper_rotations_and_unit_translations(true_pose):
    R, t = true_pose
    candidates = decompose_essential(essential_from_pose(R, t))
    assert len(candidates) == 4
    for R_c, t_c in candidates:
        np.testing.assert_allclose(R_c @ R_c.T, np.eye(3), atol=1e-12)
        assert np.linalg.det(R_c) == pytest.approx(1.0)
        assert np.linalg.norm(t_c) == pytest.approx(1.0)
    # The true pose is among them.
    t_unit = t / np.linalg.norm(t)
    assert any(np.allclose(R_c, R, atol=1e-9) and np.allclose(t_c, t_unit, atol=1e-9)
               for R_c, t_c in candidates)


@pytest.mark.parametrize("which", range(4))
def test_cheirality_picks_each_candidate_when_it_is_the_true_one(camera, true_pose, which):
    """Scenes built so that candidate `which` of one E is the real pose: it must win."""
    R, t = true_pose
    E = essential_from_pose(R, t)
    R_c, t_c = decompose_essential(E)[which]
    points = _points_in_front_of_both(R_c, t_c, seed=which)
    assert len(points) >= 50
    pts1 = project(points, camera, np.eye(3), np.zeros(3))
    pts2 = project(points, camera, R_c, t_c)
    R_est, t_est, points_est, in_front = choose_pose(E, pts1, pts2, camera)
    np.testing.assert_allclose(R_est, R_c, atol=1e-9)
    np.testing.assert_allclose(t_est, t_c, atol=1e-9)
    assert in_front.all()
    np.testing.assert_allclose(points_est, points, atol=1e-6)  # built with the unit t_c


def _points_in_front_of_both(R, t, seed, n=200):
    """Points (camera-1 frame) with positive depth in camera 1 and in camera [R | t]."""
    rng = np.random.default_rng(seed)
    points = rng.uniform([-3, -3, 0.05], [3, 3, 8], (40000, 3))
    z2 = (points @ R.T + t)[:, 2]
    return points[z2 > 0.05][:n]


def test_no_clear_winner_raises(camera, true_pose):
    """Half the points agree with one candidate, half with another: refuse to choose."""
    R, t = true_pose
    E = essential_from_pose(R, t)
    pts1, pts2 = [], []
    for which in (0, 3):
        R_c, t_c = decompose_essential(E)[which]
        points = _points_in_front_of_both(R_c, t_c, seed=which, n=60)
        pts1.append(project(points, camera, np.eye(3), np.zeros(3)))
        pts2.append(project(points, camera, R_c, t_c))
    with pytest.raises(ReconstructionError) as info:
        choose_pose(E, np.vstack(pts1), np.vstack(pts2), camera)
    assert info.value.reason == "no_cheirality_winner"
    assert info.value.counts["points"] == 120
