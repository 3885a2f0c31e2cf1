"""Non-linear refinement of two-view geometry: the robust Sampson refinement of the pose.

- :func:`refine_relative_pose` polishes ``(R, t)`` by minimising the Sampson
  distances (a first-order geometric error in pixels, H&Z section 11.4.3) of the
  inlier correspondences under a robust loss, with a small Levenberg-Marquardt
  solver in numpy (5 unknowns, analytic Jacobian, the loss's curvature in the
  normal equations).
- :func:`relative_pose_covariance` gives the first-order covariance of the refined
  pose; it and the focal fit's standard deviation (:mod:`scene3D.twoview.focal_fit`) share
  one sandwich estimate (:func:`scene3D.optim.uncertainty.sandwich_covariance`).
  :func:`pose_intrinsics_sensitivity` gives how the refined pose moves with the
  intrinsics.
- The Sampson distances and their Jacobian, the robust losses and Levenberg-Marquardt's
  loop here also serve the focal-length check (:func:`scene3D.twoview.focal_fit.fit_focal_scale`)
  and the bundle adjustments of two views
  (:func:`scene3D.optim.bundle_two_view.bundle_adjust_two_view`) and of many
  (:mod:`scene3D.optim.bundle`).

In all, ``t`` ends on the unit sphere, since a two-view translation has no scale. Frames as in
:mod:`scene3D.geometry`: ``x_cam2 = R x_cam1 + t``.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import NamedTuple

import numpy as np
from numpy.typing import ArrayLike

from ..geometry.conventions import (
    FloatArray,
    rotations_from_vectors,
    skew,
    to_homogeneous,
)
from .uncertainty import nuisance_sensitivity, sandwich_covariance, tangent_basis


def sampson_residuals(F: FloatArray, pts1: FloatArray, pts2: FloatArray) -> FloatArray:
    """Signed Sampson distances ``(N,)`` in pixels of correspondences to ``x2^T F x1 = 0``."""
    return _sampson(F, to_homogeneous(pts1), to_homogeneous(pts2))


def _sampson(F: FloatArray, h1: FloatArray, h2: FloatArray) -> FloatArray:
    """:func:`sampson_residuals` of homogeneous pixels ``(N, 3)`` (for repeated calls)."""
    Fx1 = h1 @ F.T
    Ftx2 = h2 @ F
    algebraic = np.einsum("ij,ij->i", h2, Fx1)
    norm = np.sqrt(Fx1[:, 0] ** 2 + Fx1[:, 1] ** 2 + Ftx2[:, 0] ** 2 + Ftx2[:, 1] ** 2)
    return algebraic / np.maximum(norm, 1e-300)


def _update_pose(
    R: FloatArray, t: FloatArray, dx: FloatArray, basis: FloatArray | None = None
) -> tuple[FloatArray, FloatArray]:
    """Apply a 5-vector step: rotation vector (3) and tangent step of ``t`` (2)."""
    basis = tangent_basis(t) if basis is None else basis
    R_new = rotations_from_vectors(dx[None, :3])[0] @ R
    t_new = t + dx[3:] @ basis
    return R_new, t_new / np.linalg.norm(t_new)


def _fundamental_derivatives(R: FloatArray, t: FloatArray, basis: FloatArray,
                             K_inv: FloatArray, K2_inv: FloatArray | None = None) -> FloatArray:
    """``dF / dx`` ``(5, 3, 3)`` at the pose, for the step ``x`` of :func:`_update_pose`.

    ``R <- exp([w]x) R`` gives ``dE/dw_k = [t]x [e_k]x R``; ``t <- t + d @ basis``
    (then renormalised, which is second order since ``basis`` is orthogonal to
    ``t``) gives ``dE/dd_k = [b_k]x R``; and ``F = K2^-T E K^-1`` (``K2 = K`` unless
    given: image 2's intrinsics).
    """
    K2_inv = K_inv if K2_inv is None else K2_inv
    dE = [skew(t) @ skew(axis) @ R for axis in np.eye(3)] + [skew(b) @ R for b in basis]
    return np.stack([K2_inv.T @ d @ K_inv for d in dE])


def _sampson_jacobian(F: FloatArray, dF: FloatArray, h1: FloatArray,
                      h2: FloatArray) -> FloatArray:
    """Jacobian ``(N, k)`` of :func:`_sampson` for ``F`` moving along ``dF`` ``(k, 3, 3)``.

    With ``a = x2^T F x1``, ``l = F x1``, ``m = F^T x2`` and
    ``n^2 = l_1^2 + l_2^2 + m_1^2 + m_2^2``, the distance ``a / n`` changes by
    ``(x2^T dF x1) / n - a (l' . dF x1 + x2^T dF m') / n^3`` (``l', m'``: ``l, m``
    with the third entry zeroed).
    """
    Fx1 = h1 @ F.T
    Ftx2 = h2 @ F
    a = np.einsum("ij,ij->i", h2, Fx1)
    n = np.maximum(np.sqrt(Fx1[:, 0] ** 2 + Fx1[:, 1] ** 2 + Ftx2[:, 0] ** 2
                           + Ftx2[:, 1] ** 2), 1e-300)
    Fx1[:, 2] = 0.0
    Ftx2[:, 2] = 0.0
    # d(a/n)/dF as (N, 3, 3): x2 x1^T / n - a / n^3 (l' x1^T + x2 m'^T), then one product.
    c = (a / n**3)[:, None, None]
    grad = (h2 / n[:, None])[:, :, None] * h1[:, None, :]
    grad -= c * (Fx1[:, :, None] * h1[:, None, :] + h2[:, :, None] * Ftx2[:, None, :])
    return grad.reshape(-1, 9) @ dF.reshape(len(dF), 9).T


def _loss(z: FloatArray, loss: str) -> tuple[FloatArray, FloatArray, FloatArray]:
    """scipy's robust losses ``rho(z)`` and their derivatives ``rho'``, ``rho''`` at ``z = r^2``."""
    if loss == "linear":
        return z, np.ones_like(z), np.zeros_like(z)
    if loss == "cauchy":
        rho1 = 1.0 / (1.0 + z)
        return np.log1p(z), rho1, -(rho1**2)
    if loss == "soft_l1":
        rho1 = 1.0 / np.sqrt(1.0 + z)
        return 2.0 * (np.sqrt(1.0 + z) - 1.0), rho1, -0.5 * rho1**3
    if loss == "huber":
        big = z > 1.0
        zs = np.maximum(z, 1e-300)
        return (np.where(big, 2.0 * np.sqrt(zs) - 1.0, z),
                np.where(big, 1.0 / np.sqrt(zs), 1.0),
                np.where(big, -0.5 / (zs * np.sqrt(zs)), 0.0))
    raise ValueError(f"unknown loss {loss!r}; use linear, huber, soft_l1 or cauchy")


def _robust_scaling(r: FloatArray, loss: str, scale: float) -> tuple[FloatArray, FloatArray]:
    """Row scales of the Jacobian and scaled residuals for a robust Gauss-Newton step.

    With ``z = (r / scale)^2`` and the loss ``rho(z)`` (:func:`_loss`), the rows of
    ``J`` are scaled by ``sqrt(rho' + 2 rho'' z)`` and the residuals become
    ``rho' r / sqrt(rho' + 2 rho'' z)`` (Triggs et al., "Bundle adjustment: a modern
    synthesis", section 4.3, as in scipy's ``least_squares``): the normal equations
    then hold the robust cost's gradient and a Hessian that includes the curvature
    of the loss, which converges in fewer steps than plain reweighting.
    """
    z = (r / scale) ** 2
    _, rho1, rho2 = _loss(z, loss)
    row_scale = np.sqrt(np.maximum(rho1 + 2.0 * rho2 * z, np.finfo(float).eps))
    return row_scale, rho1 * r / row_scale


def _reweighting(r: FloatArray, loss: str, scale: float) -> tuple[FloatArray, FloatArray]:
    """Row scales ``sqrt(rho')`` of the Jacobian and scaled residuals ``sqrt(rho') r``.

    Iteratively reweighted least squares, as Ceres does for losses whose curvature
    ``rho''`` is negative (all of ours): the gradient is the robust cost's, and the
    Hessian stays positive for every row. Bundle adjustment needs this: a point has
    only four rows, and where all of them are past the loss's scale the curvature-
    corrected rows of :func:`_robust_scaling` (clamped at zero, as in scipy) leave its
    3x3 block singular, so no damped step can move it, or the pose with it.
    """
    _, rho1, _ = _loss((r / scale) ** 2, loss)
    row_scale = np.sqrt(rho1)
    return row_scale, row_scale * r


def _damped_steps(J: FloatArray, r: FloatArray, loss: str,
                  scale: float) -> Callable[[float], FloatArray]:
    """Steps of robust Gauss-Newton on residuals ``r`` ``(N,)`` with Jacobian ``J`` ``(N, k)``.

    Builds the normal equations once, with the rows of :func:`_robust_scaling`, and
    returns ``step(damping) -> dx`` ``(k,)`` with Marquardt's damping of their diagonal.
    """
    row_scale, rw = _robust_scaling(r, loss, scale)
    Jw = J * row_scale[:, None]
    H, g = Jw.T @ Jw, Jw.T @ rw
    damped = np.diag(np.diag(H) + 1e-12)
    return lambda damping: np.linalg.solve(H + damping * damped, -g)


def _robust_covariance(J: FloatArray, r: FloatArray, loss: str, scale: float) -> FloatArray:
    """Covariance ``(k, k)`` of the robust fit whose residuals ``r`` ``(N,)`` have Jacobian
    ``J`` ``(N, k)`` at the optimum (:func:`scene3D.optim.uncertainty.sandwich_covariance`).

    The cost ``scale^2 rho((r / scale)^2)`` has the influence ``psi = rho' r`` and
    its slope ``psi' = rho' + 2 rho'' z`` (the row scales of :func:`_robust_scaling`,
    squared, here without their clamp at zero).
    """
    z = (r / scale) ** 2
    _, rho1, rho2 = _loss(z, loss)
    return sandwich_covariance(J, rho1 * r, rho1 + 2.0 * rho2 * z)


def _robust_cost(r: FloatArray, loss: str, scale: float) -> float:
    """``scale^2 * sum rho((r / scale)^2)``, the cost the refinement minimises."""
    return float(scale**2 * np.sum(_loss((r / scale) ** 2, loss)[0]))


def _levenberg_marquardt(
    state: tuple, cost: float, linearize: Callable[[tuple], Callable[[float], tuple]],
    max_iterations: int, min_decrease: float,
) -> tuple:
    """Levenberg-Marquardt's outer loop: damping, acceptance and stopping.

    ``linearize(state)`` builds the normal equations at ``state`` and returns
    ``try_step(damping) -> (new_state, new_cost)``. A step is accepted when it
    lowers the cost (then the damping falls tenfold, else it rises tenfold and the
    step is solved again); the loop stops when a step gains less than
    ``min_decrease`` of the cost, none can be found, or after ``max_iterations``.
    """
    damping = 1e-3
    for _ in range(max_iterations):
        try_step = linearize(state)
        improved = False
        while damping < 1e8:
            new_state, new_cost = try_step(damping)
            if new_cost < cost:
                improved = cost - new_cost > min_decrease * max(cost, 1e-30)
                state, cost = new_state, new_cost
                damping = max(damping / 10.0, 1e-9)
                break
            damping *= 10.0
        if not improved:
            break
    return state


def _refine_pose_and_one(
    R: FloatArray, t: FloatArray, x0: float,
    residuals: Callable[[FloatArray, FloatArray, float], tuple[FloatArray, object]],
    jacobian: Callable[[FloatArray, FloatArray, float, FloatArray, object], FloatArray],
    max_abs: float, loss: str, scale_px: float, max_iterations: int,
) -> tuple[FloatArray, FloatArray, float, float]:
    """The robust refinement of a pose ``R, t`` (``|t| = 1``) and one more unknown ``x``
    from ``x0``: the focal checks' factor, the distortion check's coefficient.

    ``residuals(R, t, x) -> (r, cache)`` gives the signed distances ``(N,)`` in pixels
    and whatever ``jacobian(R, t, x, basis, cache) -> J`` ``(N, 6)`` reuses (columns: the
    pose step of :func:`_update_pose` in the tangent ``basis`` of ``t``, then ``x``).
    Levenberg-Marquardt does not step beyond ``|x| <= max_abs``. Returns the refined
    ``R, t, x`` and the first-order standard deviation of ``x`` (the sandwich of
    :func:`_robust_covariance`; inf when the matches do not determine it).
    """
    def evaluate(R_: FloatArray, t_: FloatArray, x: float) -> tuple[tuple, float]:
        if not abs(x) <= max_abs:
            return (R_, t_, x, None, None), np.inf  # a step Levenberg-Marquardt rejects
        r_, cache = residuals(R_, t_, x)
        return (R_, t_, x, r_, cache), _robust_cost(r_, loss, scale_px)

    def full_jacobian(state: tuple) -> tuple[FloatArray, FloatArray]:
        R_, t_, x, _, cache = state
        basis = tangent_basis(t_)
        return jacobian(R_, t_, x, basis, cache), basis

    def linearize(state: tuple) -> Callable[[float], tuple]:
        R_, t_, x, r_, _ = state
        J, basis = full_jacobian(state)
        step = _damped_steps(J, r_, loss, scale_px)

        def try_step(damping: float) -> tuple[tuple, float]:
            dx = step(damping)
            return evaluate(*_update_pose(R_, t_, dx[:5], basis), x + dx[5])
        return try_step

    state, cost = evaluate(R, t, float(x0))
    state = _levenberg_marquardt(state, cost, linearize, max_iterations, 1e-10)
    variance = _robust_covariance(full_jacobian(state)[0], state[3], loss, scale_px)[5, 5]
    sigma = float(np.sqrt(variance)) if 0 < variance < np.inf else np.inf
    return state[0], state[1], state[2], sigma


def refine_relative_pose(
    R: ArrayLike,
    t: ArrayLike,
    pts1: ArrayLike,
    pts2: ArrayLike,
    K: ArrayLike,
    loss: str = "cauchy",
    scale_px: float = 0.5,
    max_iterations: int = 30,
) -> tuple[FloatArray, FloatArray]:
    """Refine a relative pose by minimising robust Sampson distances (Levenberg-Marquardt).

    Parameters
    ----------
    R, t : (3, 3), (3,) array_like
        Initial pose, ``x_cam2 = R x_cam1 + t``.
    pts1, pts2 : (N, 2) array_like
        Inlier pixels (N >= 5).
    K : (3, 3) array_like
        Intrinsics shared by both views.
    loss, scale_px : str, float
        Robust loss (``"linear"``, ``"huber"``, ``"soft_l1"``, ``"cauchy"``, as in
        scipy) and its scale in pixels.

    Returns
    -------
    R, t : (3, 3), (3,) float64
        Refined pose; ``|t| = 1``.
    """
    R = np.asarray(R, dtype=np.float64)
    t = np.asarray(t, dtype=np.float64).reshape(3)
    t = t / np.linalg.norm(t)
    p1 = np.asarray(pts1, dtype=np.float64)
    p2 = np.asarray(pts2, dtype=np.float64)
    K = np.asarray(K, dtype=np.float64)

    K_inv = np.linalg.inv(K)
    h1, h2 = to_homogeneous(p1), to_homogeneous(p2)

    def fundamental(R_: FloatArray, t_: FloatArray) -> FloatArray:
        return K_inv.T @ skew(t_) @ R_ @ K_inv  # F = K^-T [t]x R K^-1

    def evaluate(R_: FloatArray, t_: FloatArray) -> tuple[tuple, float]:
        F_ = fundamental(R_, t_)
        r_ = _sampson(F_, h1, h2)
        return (R_, t_, F_, r_), _robust_cost(r_, loss, scale_px)

    def linearize(state: tuple) -> Callable[[float], tuple]:
        R_, t_, F_, r_ = state
        basis = tangent_basis(t_)
        J = _sampson_jacobian(F_, _fundamental_derivatives(R_, t_, basis, K_inv), h1, h2)
        step = _damped_steps(J, r_, loss, scale_px)
        return lambda damping: evaluate(*_update_pose(R_, t_, step(damping), basis))

    state, cost = evaluate(R, t)
    R, t, _, _ = _levenberg_marquardt(state, cost, linearize, max_iterations, 1e-8)
    return R, t


class _SampsonAt(NamedTuple):
    """The Sampson residuals' ingredients at a pose (:func:`_sampson_at`)."""

    R: FloatArray  # (3, 3)
    t: FloatArray  # (3,), unit norm
    K_inv: FloatArray  # (3, 3)
    h1: FloatArray  # (N, 3) homogeneous pixels of image 1
    h2: FloatArray  # (N, 3) of image 2
    F: FloatArray  # (3, 3), K^-T [t]x R K^-1
    J_pose: FloatArray  # (N, 5) Sampson distances by the pose step


def _sampson_at(R: ArrayLike, t: ArrayLike, pts1: ArrayLike, pts2: ArrayLike,
                K: ArrayLike) -> _SampsonAt:
    """The pose (``t`` normalised), ``K^-1``, the points, ``F`` and the Jacobian of the
    Sampson distances by the pose step (parametrisation of :mod:`scene3D.optim.uncertainty`)."""
    R = np.asarray(R, dtype=np.float64)
    t = np.asarray(t, dtype=np.float64).reshape(3)
    t = t / np.linalg.norm(t)
    K_inv = np.linalg.inv(np.asarray(K, dtype=np.float64))
    h1 = to_homogeneous(np.asarray(pts1, dtype=np.float64))
    h2 = to_homogeneous(np.asarray(pts2, dtype=np.float64))
    F = K_inv.T @ skew(t) @ R @ K_inv
    J = _sampson_jacobian(F, _fundamental_derivatives(R, t, tangent_basis(t), K_inv), h1, h2)
    return _SampsonAt(R, t, K_inv, h1, h2, F, J)


def relative_pose_covariance(
    R: ArrayLike,
    t: ArrayLike,
    pts1: ArrayLike,
    pts2: ArrayLike,
    K: ArrayLike,
    loss: str = "cauchy",
    scale_px: float = 0.5,
) -> FloatArray:
    """First-order covariance ``(5, 5)`` of the pose that :func:`refine_relative_pose` found.

    At the optimum ``(R, t)`` of the robust Sampson cost over the inliers
    ``pts1, pts2`` (the same ``loss`` and ``scale_px``), the sandwich covariance of
    the M-estimate (:func:`scene3D.optim.uncertainty.sandwich_covariance`) from the
    Jacobian of the Sampson distances, the loss's weights and the distances
    themselves: the noise is measured by the residuals, not assumed. The
    parametrisation is the refinement's step (:mod:`scene3D.optim.uncertainty`):
    ``R <- exp([w]x) R`` (``w`` in the camera-2 frame) and ``t`` along the rows of
    :func:`scene3D.optim.uncertainty.tangent_basis` ``(t)``, in radians^2. The Sampson
    distance is the reprojection error with the points eliminated, to first order
    (H&Z section 11.4.3), so this is also the first-order covariance of a two-view
    bundle adjustment's pose.

    Parameters
    ----------
    R, t : (3, 3), (3,) array_like
        The refined pose, ``x_cam2 = R x_cam1 + t`` (any of the decompositions of
        its essential matrix: the covariance refers to the one given).
    pts1, pts2 : (N, 2) array_like
        The inlier pixels it was refined on.
    K : (3, 3) array_like
    loss, scale_px : str, float
        The refinement's robust loss and scale.

    Returns
    -------
    (5, 5) float64
        Infinite when the matches do not determine the pose (fewer than six, or a
        singular Hessian).
    """
    at = _sampson_at(R, t, pts1, pts2, K)
    return _robust_covariance(at.J_pose, _sampson(at.F, at.h1, at.h2), loss, scale_px)


def pose_intrinsics_sensitivity(
    R: ArrayLike,
    t: ArrayLike,
    pts1: ArrayLike,
    pts2: ArrayLike,
    K: ArrayLike,
    loss: str = "cauchy",
    scale_px: float = 0.5,
) -> FloatArray:
    """How the refined pose moves with the intrinsics it was refined under ``(5, 3)``.

    At the optimum ``(R, t)`` of the robust Sampson cost over the inliers
    ``pts1, pts2`` ``(N, 2)`` under ``K`` (as :func:`relative_pose_covariance`), the
    first-order change of the pose step ``x`` (5, parametrisation of
    :mod:`scene3D.optim.uncertainty`: rotation vector in the camera-2 frame, then the
    direction step along ``tangent_basis(t)``, radians) per unit change of the
    intrinsics ``theta = (log f, c_x, c_y)``: both focal lengths scaled by
    ``exp(log f)``, the principal point (both views, pixels) moved. Columns: by
    ``log f``, by ``c_x``, by ``c_y``
    (:func:`scene3D.optim.uncertainty.nuisance_sensitivity`). With a covariance of
    ``theta`` it turns the pose's covariance under a known ``K`` into one for a
    ``K`` known only that well (:func:`scene3D.optim.uncertainty.marginal_covariance`).
    """
    at = _sampson_at(R, t, pts1, pts2, K)
    K = np.asarray(K, dtype=np.float64)
    K_inv, E = at.K_inv, skew(at.t) @ at.R
    dK = [np.diag([K[0, 0], K[1, 1], 0.0]), np.zeros((3, 3)), np.zeros((3, 3))]
    dK[1][0, 2] = dK[2][1, 2] = 1.0
    # d(K^-1) = -K^-1 dK K^-1, and F = K^-T E K^-1.
    dF_theta = []
    for d in dK:
        dK_inv = -K_inv @ d @ K_inv
        dF_theta.append(dK_inv.T @ E @ K_inv + K_inv.T @ E @ dK_inv)
    J_pose = at.J_pose
    J_theta = _sampson_jacobian(at.F, np.stack(dF_theta), at.h1, at.h2)
    r = _sampson(at.F, at.h1, at.h2)
    z = (r / scale_px) ** 2
    _, rho1, rho2 = _loss(z, loss)
    return nuisance_sensitivity(J_pose, J_theta, rho1 + 2.0 * rho2 * z)
