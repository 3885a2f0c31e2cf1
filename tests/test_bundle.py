"""Bundle adjustment with one shared focal length: the Jacobians, the Schur solve with a
global unknown, convergence from a focal length 30 % off, and its standard deviation."""

import numpy as np
import pytest

from scene3D.evaluation.synthetic import orbit_poses
from scene3D.geometry import project, rotations_from_vectors
from scene3D.geometry.camera import with_focal
from scene3D.optim.bundle import (
    Observations,
    bundle_adjust,
    bundle_adjust_focal,
    reprojection_jacobians,
    reprojection_residuals,
)
from scene3D.optim.schur import global_information, normal_equations, solve_damped_global

#: Square pixels (the model refined), the principal point off the centre of 640 x 480.
K_TRUE = np.array([[700.0, 0, 333.0], [0, 700.0, 231.0], [0, 0, 1]])


def _orbit_observations(noise_px=0.0, seed=0, views=12, points=1500):
    """Points in the courtyard of :func:`scene3D.evaluation.synthetic.orbit_poses`, seen by the
    views that have them in front and inside 640 x 480; points seen once are dropped."""
    rng = np.random.default_rng(seed)
    Rs, ts = orbit_poses(views)
    X = rng.uniform([-8, -4, -8], [8, 2, 8], (points, 3))
    view, point, xy = [], [], []
    for v, (R, t) in enumerate(zip(Rs, ts)):
        pix = project(X, K_TRUE, R, t)
        depth = (X @ R.T + t)[:, 2]
        seen = np.flatnonzero((depth > 0) & np.all((pix > 0) & (pix < [640, 480]), axis=1))
        view.append(np.full(len(seen), v))
        point.append(seen)
        xy.append(pix[seen] + rng.normal(0, noise_px, (len(seen), 2)))
    view, point, xy = np.concatenate(view), np.concatenate(point), np.vstack(xy)
    keep = np.bincount(point, minlength=points)[point] >= 2
    return Rs, ts, X, Observations(view[keep], point[keep], xy[keep])


def test_jacobians_match_finite_differences():
    Rs, ts, X, obs = _orbit_observations(views=5, points=60)
    K = with_focal(K_TRUE, 760.0)
    J_camera, J_point, J_focal = reprojection_jacobians(Rs, ts, X, obs, K)
    r0 = reprojection_residuals(Rs, ts, X, obs, K)
    eps = 1e-6
    # The focal length: log f, both focal lengths together, the principal point held.
    r = reprojection_residuals(Rs, ts, X, obs, with_focal(K, 760.0 * np.exp(eps)))
    np.testing.assert_allclose((r - r0) / eps, J_focal[:, :, 0], atol=1e-3)
    # A camera: R <- exp([w]x) R, t <- t + dt (view 2's observations only).
    on = obs.view == 2
    for k in range(6):
        step = np.zeros(6)
        step[k] = eps
        R_, t_ = Rs.copy(), ts.copy()
        R_[2] = rotations_from_vectors(step[None, :3])[0] @ Rs[2]
        t_[2] = ts[2] + step[3:]
        r = reprojection_residuals(R_, t_, X, obs, K)
        np.testing.assert_allclose((r - r0)[on] / eps, J_camera[on, :, k], atol=1e-3)
        assert np.all(r[~on] == r0[~on])
    # A point.
    on = obs.point == obs.point[0]
    for k in range(3):
        X_ = X.copy()
        X_[obs.point[0], k] += eps
        r = reprojection_residuals(Rs, ts, X_, obs, K)
        np.testing.assert_allclose((r - r0)[on] / eps, J_point[on, :, k], atol=1e-3)


@pytest.mark.parametrize("views, points", [(4, 40), (36, 120)])
def test_schur_solve_with_a_global_unknown_equals_the_dense_solve(views, points):
    """Every camera but 0 free, the points, one global unknown (4 views: the dense Schur
    product; 36: the sparse one): the step from the reduced system equals the dense solve
    of the damped normal equations, and the marginal information equals the dense one's."""
    rng = np.random.default_rng(1)
    Rs, ts, X, obs = _orbit_observations(views=views, points=points)
    ids, point = np.unique(obs.point, return_inverse=True)
    obs = Observations(obs.view, point, obs.xy)
    n_obs, P = len(obs.view), len(ids)
    J_camera = rng.normal(size=(n_obs, 2, 6))
    J_point = rng.normal(size=(n_obs, 2, 3))
    J_global = rng.normal(size=(n_obs, 2, 1))
    r = rng.normal(size=(n_obs, 2))
    camera = obs.view - 1  # view 0 fixed: -1
    C = views - 1
    ne = normal_equations(J_camera, camera, J_point, obs.point, r, C, P, J_global)
    # Dense: columns = cameras (6 each), global, points (3 each).
    n = 6 * C + 1 + 3 * P
    J = np.zeros((2 * n_obs, n))
    for o in range(n_obs):
        rows = slice(2 * o, 2 * o + 2)
        if camera[o] >= 0:
            J[rows, 6 * camera[o]:6 * camera[o] + 6] = J_camera[o]
        J[rows, 6 * C] = J_global[o, :, 0]
        J[rows, 6 * C + 1 + 3 * obs.point[o]:6 * C + 4 + 3 * obs.point[o]] = J_point[o]
    H, g = J.T @ J, J.T @ r.ravel()
    damping = 0.01
    dense = np.linalg.solve(H + damping * np.diag(np.diag(H) + 1e-12), -g)
    step_camera, step_global, step_point = solve_damped_global(ne, damping)
    np.testing.assert_allclose(step_camera.ravel(), dense[:6 * C], rtol=1e-7, atol=1e-10)
    np.testing.assert_allclose(step_global, dense[6 * C:6 * C + 1], rtol=1e-7, atol=1e-10)
    np.testing.assert_allclose(step_point.ravel(), dense[6 * C + 1:], rtol=1e-7, atol=1e-10)
    info = np.linalg.inv(np.linalg.inv(H)[6 * C:6 * C + 1, 6 * C:6 * C + 1])
    np.testing.assert_allclose(global_information(ne), info, rtol=1e-7)


def test_without_a_focal_the_adjustment_is_unchanged():
    Rs, ts, X, obs = _orbit_observations(0.3, views=6, points=300)
    rng = np.random.default_rng(2)
    X0 = X + rng.normal(0, 0.05, X.shape)
    R1, t1, X1 = bundle_adjust(Rs, ts, X0, obs, K_TRUE, fixed_view=0)
    res = bundle_adjust_focal(Rs, ts, X0, obs, K_TRUE, 0, 700.0, 1e-9)  # the focal pinned
    np.testing.assert_allclose(res.focal_px, 700.0, rtol=1e-8)
    np.testing.assert_allclose(res.R, R1, atol=1e-8)
    np.testing.assert_allclose(res.points3d, X1, atol=1e-6)


@pytest.mark.parametrize("noise_px", [0.0, 0.5])
@pytest.mark.parametrize("start", [1.3, 0.7])
def test_a_focal_length_30_percent_off_converges_to_the_truth(noise_px, start):
    """From a focal length 30 % too long or too short, with the default prior (1.2 x the
    longer side, sigma 0.5 in log f) at the wrong value: noise-free, the truth to 1e-8;
    with 0.5 px of noise, within three of its standard deviations and 0.1 %."""
    Rs, ts, X, obs = _orbit_observations(noise_px)
    rng = np.random.default_rng(3)
    X0 = X * 1.02 + rng.normal(0, 0.05, X.shape)
    K0 = with_focal(K_TRUE, 700.0 * start)
    res = bundle_adjust_focal(Rs, ts, X0, obs, K0, 0, 1.2 * 640, 0.5,
                              principal_point_shift_px=6.4)
    error = res.focal_px / 700.0 - 1.0
    np.testing.assert_allclose(res.K[[0, 1], [2, 2]], K_TRUE[[0, 1], [2, 2]])
    assert res.K[0, 0] == res.K[1, 1] == res.focal_px
    if noise_px == 0.0:
        assert abs(error) < 1e-8 and res.noise_px < 1e-4
    else:
        assert abs(error) < 1e-3
        assert abs(np.log1p(error)) < 3.0 * res.sigma_log
        assert 0.3 < res.noise_px < 0.5  # 0.5 px less what the points absorb
        assert res.sigma_log < 5e-4
    # The principal point's share: 1 % of the width moves this collection's focal length
    # by about 0.1 %, far more than the noise does.
    assert 3e-4 < res.principal_point_sigma_log < 3e-3
    assert res.total_sigma_log == pytest.approx(np.hypot(res.sigma_log,
                                                         res.principal_point_sigma_log))


def test_the_sigma_follows_the_scatter_over_noise_draws():
    """The standard deviation the adjustment gives matches the scatter of the focal
    lengths it finds over independent noise draws (within the sampling error of 12)."""
    found, sigmas = [], []
    for seed in range(12):
        Rs, ts, X, obs = _orbit_observations(1.0, seed=seed, views=8, points=400)
        res = bundle_adjust_focal(Rs, ts, X, obs, K_TRUE, 0, 840.0, 0.5, loss="linear")
        found.append(np.log(res.focal_px / 700.0))
        sigmas.append(res.sigma_log)
    ratio = np.sqrt(np.mean(np.square(found))) / np.median(sigmas)
    assert 0.5 < ratio < 1.6


def test_views_that_do_not_rotate_leave_the_focal_length_to_the_prior():
    """Views that translate without turning: scaling the focal length and the depths
    together changes no projection (H&Z section 19.5), so the adjustment keeps the prior's
    focal length and its sigma."""
    rng = np.random.default_rng(4)
    X = rng.uniform([-3, -2, 8], [3, 2, 12], (400, 3))
    Rs = np.repeat(np.eye(3)[None], 4, axis=0)
    ts = -np.array([[0.4 * v, 0.1 * v, 0.0] for v in range(4)])
    view, point, xy = [], [], []
    for v in range(4):
        view.append(np.full(len(X), v))
        point.append(np.arange(len(X)))
        xy.append(project(X, K_TRUE, Rs[v], ts[v]) + rng.normal(0, 0.5, (len(X), 2)))
    obs = Observations(np.concatenate(view), np.concatenate(point), np.vstack(xy))
    res = bundle_adjust_focal(Rs, ts, X, obs, with_focal(K_TRUE, 910.0), [0, 1], 910.0, 0.5)
    assert res.focal_px == pytest.approx(910.0, rel=1e-3)
    assert res.sigma_log > 0.4  # the photos add next to nothing to the prior's 0.5
    assert res.noise_px < 0.6  # the depths followed the focal length
