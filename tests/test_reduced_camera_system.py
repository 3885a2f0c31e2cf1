"""The reduced camera system of many cameras: the sparse and the iterative solves against the
dense one (random well-posed systems, an ill-conditioned one with a free scale), the camera
count that picks the method, and a bundle adjustment of 200 cameras with each."""

import numpy as np
import pytest

from scene3D.evaluation.synthetic import outward_ring
from scene3D.geometry import project, rotations_from_vectors
from scene3D.optim import schur
from scene3D.optim.bundle import Observations, bundle_adjust, reprojection_jacobians
from scene3D.optim.conjugate_gradients import preconditioned_conjugate_gradients
from scene3D.optim.schur import (
    normal_equations,
    schur_matrix_sparse,
    schur_product_dense,
    solve_damped,
    solve_damped_global,
)

#: fx != fy, the principal point off the centre of 640 x 480.
K = np.array([[700.0, 0, 333.0], [0, 690.0, 231.0], [0, 0, 1]])


def _ring(num_cameras, points_per_camera=130, seed=0, spacing=0.5):
    """:func:`scene3D.evaluation.synthetic.outward_ring`, 130 points per camera by default."""
    return outward_ring(num_cameras, points_per_camera, seed, spacing)


def _random_system(num_cameras, num_points, seed=0, global_unknowns=0):
    """Random Jacobian blocks on the ring's covisibility, camera 0 fixed: well posed."""
    rng = np.random.default_rng(seed)
    _, _, _, view, point = _ring(num_cameras, 4 * num_points // num_cameras, seed)
    n = len(view)
    J_global = rng.normal(size=(n, 2, global_unknowns)) if global_unknowns else None
    return normal_equations(rng.normal(size=(n, 2, 6)), view - 1, rng.normal(size=(n, 2, 3)),
                            point, rng.normal(size=(n, 2)), num_cameras - 1,
                            point.max() + 1, J_global)


def _relative(a, b):
    return np.linalg.norm(a - b) / np.linalg.norm(b)


@pytest.mark.parametrize("method", ["sparse", "iterative"])
@pytest.mark.parametrize("global_unknowns", [0, 1])
def test_many_cameras_solve_equals_the_dense_solve(method, global_unknowns):
    """60 cameras, 2000 points: each step (cameras, global, points) within 1e-8 of the
    dense solve's."""
    ne = _random_system(60, 2000, seed=3, global_unknowns=global_unknowns)
    dense = solve_damped_global(ne, 1e-3, method="dense")
    other = solve_damped_global(ne, 1e-3, method=method)
    for a, b in zip(other, dense):
        if b.size:
            assert _relative(a, b) < 1e-8


def test_the_sparse_schur_matrix_equals_the_dense_product():
    ne = _random_system(30, 600, seed=5)
    Y = ne.W @ np.linalg.inv(ne.V)[ne.point]
    dense = schur_product_dense(Y, ne.W, ne.camera, ne.point, 29)
    S = schur_matrix_sparse(Y, ne.W, ne.camera, ne.point, 29, chunk_pairs=777).toarray()
    np.testing.assert_allclose(S, dense, rtol=0, atol=1e-12 * np.abs(dense).max())
    # Cameras 10 apart on the ring share no point: their block is stored as zero.
    assert np.all(S[:6, 60:66] == 0) and np.abs(S[:6, 6:12]).max() > 0


def test_the_camera_count_picks_the_method(monkeypatch):
    """``auto`` gives the dense solve's bits below the threshold and the sparse solve's from it."""
    ne = _random_system(40, 1200, seed=7)
    dense = solve_damped(ne, 1e-3, method="dense")
    sparse = solve_damped(ne, 1e-3, method="sparse")
    assert not np.array_equal(dense[0], sparse[0])  # rounding tells them apart
    monkeypatch.setattr(schur, "LARGE_SCHUR_CAMERAS", 40)  # 39 free cameras: below
    assert all(np.array_equal(a, b) for a, b in zip(solve_damped(ne, 1e-3), dense))
    monkeypatch.setattr(schur, "LARGE_SCHUR_CAMERAS", 39)
    assert all(np.array_equal(a, b) for a, b in zip(solve_damped(ne, 1e-3), sparse))
    monkeypatch.setattr(schur, "LARGE_SCHUR_METHOD", "iterative")
    iterative = solve_damped(ne, 1e-3)
    assert not np.array_equal(iterative[0], sparse[0]) and _relative(iterative[0], dense[0]) < 1e-8
    with pytest.raises(ValueError, match="method"):
        solve_damped(ne, 1e-3, method="cholesky")


def _linearised_cost(ne_inputs, step_camera, step_point):
    J_camera, camera, J_point, point, r = ne_inputs
    lin = r + np.einsum("oij,oj->oi", J_point, step_point[point])
    free = camera >= 0
    lin[free] += np.einsum("oij,oj->oi", J_camera[free], step_camera[camera[free]])
    return float((lin**2).sum())


@pytest.mark.parametrize("damping", [1e-3, 1e-9])
def test_a_free_scale_and_drift_leave_the_step_as_good(damping):
    """Reprojection Jacobians of a 40-camera ring, one camera fixed: the scale is free (held by
    the damping alone) and the ring drifts softly (condition number ~1e10 at damping 1e-9).
    The sparse step equals the dense one; the iterative step lowers the linearised cost as
    much to 1e-8 (it may differ along the directions that move no residual)."""
    R, t, X, view, point = _ring(40, seed=2)
    obs = Observations(view, point, np.zeros((len(view), 2)))
    J_camera, J_point, _ = reprojection_jacobians(R, t, X, obs, K)
    r = np.random.default_rng(4).normal(size=(len(view), 2))
    inputs = (J_camera, view - 1, J_point, point, r)
    ne = normal_equations(J_camera, view - 1, J_point, point, r, 39, len(X))
    dense = solve_damped(ne, damping, method="dense")
    sparse = solve_damped(ne, damping, method="sparse")
    iterative = solve_damped(ne, damping, method="iterative")
    assert _relative(sparse[0], dense[0]) < 1e-6 and _relative(sparse[1], dense[1]) < 1e-6
    before = float((r**2).sum())
    gain = before - _linearised_cost(inputs, *dense)
    assert gain > 0
    for step in (sparse, iterative):
        assert abs(before - _linearised_cost(inputs, *step) - gain) < 1e-8 * gain


def test_conjugate_gradients_solve_a_positive_definite_system():
    rng = np.random.default_rng(0)
    A = rng.normal(size=(80, 80))
    S = A @ A.T + 80 * np.eye(80)
    b = rng.normal(size=80)
    diagonal = 1 / np.diag(S)
    result = preconditioned_conjugate_gradients(S.dot, b, lambda r: diagonal * r, 1e-12)
    assert result.converged and result.relative_residual <= 1e-12
    np.testing.assert_allclose(result.x, np.linalg.solve(S, b), rtol=1e-9)
    zero = preconditioned_conjugate_gradients(S.dot, np.zeros(80), lambda r: r)
    assert zero.iterations == 0 and np.all(zero.x == 0)


def test_a_bundle_adjustment_of_200_cameras_converges_alike(monkeypatch):
    """200 cameras, 0.5 px noise, poses and points perturbed: the adjustment reaches the same
    cost (to 1e-6) with the dense, the sparse and the iterative solves, and points as far
    from the truth, up to the scale that one fixed camera leaves free (the steps differ
    along the ring's soft bending, which the cost hardly sees)."""
    rng = np.random.default_rng(9)
    R, t, X, view, point = _ring(200, points_per_camera=80, seed=9)
    xy = np.empty((len(view), 2))
    for v in range(200):
        on = view == v
        xy[on] = project(X[point[on]], K, R[v], t[v])
    obs = Observations(view, point, xy + rng.normal(0, 0.5, xy.shape))
    R0 = rotations_from_vectors(rng.normal(0, 0.002, (200, 3))) @ R
    t0 = t + rng.normal(0, 0.01, t.shape)
    R0[0], t0[0] = R[0], t[0]
    X0 = X + rng.normal(0, 0.02, X.shape)
    results = {}
    for method in ("dense", "sparse", "iterative"):
        monkeypatch.setattr(schur, "LARGE_SCHUR_CAMERAS", 1 if method != "dense" else 10**9)
        monkeypatch.setattr(schur, "LARGE_SCHUR_METHOD", "iterative" if method == "iterative"
                            else "sparse")
        results[method] = bundle_adjust(R0, t0, X0, obs, K, fixed_view=0, loss="linear")
    cost = {m: float((((project_all(*results[m], obs)) - obs.xy) ** 2).sum()) for m in results}
    start = float(((project_all(R0, t0, X0, obs) - obs.xy) ** 2).sum())
    assert cost["dense"] < 0.01 * start
    for m in ("sparse", "iterative"):
        assert abs(cost[m] - cost["dense"]) < 1e-6 * cost["dense"]
        np.testing.assert_allclose(_in_unit_scale(results[m][2], R[0], t[0]),
                                   _in_unit_scale(results["dense"][2], R[0], t[0]), atol=1e-4)
    truth = _in_unit_scale(X, R[0], t[0])
    error = {m: np.sqrt(((_in_unit_scale(results[m][2], R[0], t[0]) - truth) ** 2).mean())
             for m in results}
    assert error["dense"] < 0.01
    assert all(abs(error[m] - error["dense"]) < 0.05 * error["dense"] for m in results)


def _in_unit_scale(X, R0, t0):
    """Points in the fixed camera's frame, scaled to unit mean distance."""
    local = X @ R0.T + t0
    return local / np.linalg.norm(local, axis=1).mean()


def project_all(R, t, X, obs):
    out = np.empty((len(obs.view), 2))
    for v in np.unique(obs.view):
        on = obs.view == v
        out[on] = project(X[obs.point[on]], K, R[v], t[v])
    return out
