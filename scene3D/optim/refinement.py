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
- :func:`refine_pose_and_parameter` refines a pose and one more unknown: the focal-length
  check's factor (:func:`scene3D.twoview.focal_fit.fit_focal_scale`) and the distortion
  check's coefficient (:mod:`scene3D.twoview.distortion_fit`).

The Sampson distances and their Jacobian are in :mod:`scene3D.geometry.epipolar`; the robust
losses and Levenberg-Marquardt's loop, which the bundle adjustments share, in
:mod:`scene3D.optim.least_squares`.

In all, ``t`` ends on the unit sphere, since a two-view translation has no scale. Frames as in
:mod:`scene3D.geometry`: ``x_cam2 = R x_cam1 + t``.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import NamedTuple

import numpy as np
from numpy.typing import ArrayLike

from ..geometry.conventions import FloatArray, skew, to_homogeneous
from ..geometry.epipolar import (
    fundamental_derivatives,
    sampson_jacobian,
    sampson_residuals,  # noqa: F401 (its old path, scene3D.optim.refinement.sampson_residuals)
    sampson_residuals_homogeneous,
)
from .least_squares import (
    damped_steps,
    levenberg_marquardt,
    robust_cost,
    robust_covariance,
    robust_loss,
)
from .uncertainty import nuisance_sensitivity, tangent_basis, update_pose


def refine_pose_and_parameter(
    R: FloatArray, t: FloatArray, x0: float,
    residuals: Callable[[FloatArray, FloatArray, float], tuple[FloatArray, object]],
    jacobian: Callable[[FloatArray, FloatArray, float, FloatArray, object], FloatArray],
    max_abs: float, loss: str, scale_px: float, max_iterations: int,
) -> tuple[FloatArray, FloatArray, float, float]:
    """The robust refinement of a pose ``R, t`` and one more unknown ``x`` from ``x0``.

    The focal checks' factor and the distortion check's coefficient are refined this way,
    with Levenberg-Marquardt (:func:`scene3D.optim.least_squares.levenberg_marquardt`) on the
    robust cost of the problem's residuals.

    Parameters
    ----------
    R, t : (3, 3), (3,) array
        The starting pose, ``x_cam2 = R x_cam1 + t``, ``|t| = 1``.
    x0 : float
        The starting value of the extra unknown.
    residuals : callable
        ``residuals(R, t, x) -> (r, cache)``: the signed distances ``r`` ``(N,)`` in pixels
        and whatever ``jacobian`` reuses.
    jacobian : callable
        ``jacobian(R, t, x, basis, cache) -> J`` ``(N, 6)``; columns: the pose step of
        :func:`scene3D.optim.uncertainty.update_pose` in the tangent ``basis`` of ``t``,
        then ``x``.
    max_abs : float
        Levenberg-Marquardt does not step beyond ``|x| <= max_abs``.
    loss, scale_px : str, float
        The robust loss (:data:`scene3D.optim.least_squares.LOSSES`) and its scale in pixels.
    max_iterations : int

    Returns
    -------
    R, t : (3, 3), (3,) float64
        The refined pose, ``|t| = 1``.
    x : float
        The refined unknown.
    sigma : float
        Its first-order standard deviation (the sandwich of
        :func:`scene3D.optim.least_squares.robust_covariance`); inf when the matches do not
        determine it.
    """
    def evaluate(R_: FloatArray, t_: FloatArray, x: float) -> tuple[tuple, float]:
        if not abs(x) <= max_abs:
            return (R_, t_, x, None, None), np.inf  # a step Levenberg-Marquardt rejects
        r_, cache = residuals(R_, t_, x)
        return (R_, t_, x, r_, cache), robust_cost(r_, loss, scale_px)

    def full_jacobian(state: tuple) -> tuple[FloatArray, FloatArray]:
        R_, t_, x, _, cache = state
        basis = tangent_basis(t_)
        return jacobian(R_, t_, x, basis, cache), basis

    def linearize(state: tuple) -> Callable[[float], tuple]:
        R_, t_, x, r_, _ = state
        J, basis = full_jacobian(state)
        step = damped_steps(J, r_, loss, scale_px)

        def try_step(damping: float) -> tuple[tuple, float]:
            dx = step(damping)
            return evaluate(*update_pose(R_, t_, dx[:5], basis), x + dx[5])
        return try_step

    state, cost = evaluate(R, t, float(x0))
    state = levenberg_marquardt(state, cost, linearize, max_iterations, 1e-10)
    variance = robust_covariance(full_jacobian(state)[0], state[3], loss, scale_px)[5, 5]
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
        r_ = sampson_residuals_homogeneous(F_, h1, h2)
        return (R_, t_, F_, r_), robust_cost(r_, loss, scale_px)

    def linearize(state: tuple) -> Callable[[float], tuple]:
        R_, t_, F_, r_ = state
        basis = tangent_basis(t_)
        J = sampson_jacobian(F_, fundamental_derivatives(R_, t_, basis, K_inv), h1, h2)
        step = damped_steps(J, r_, loss, scale_px)
        return lambda damping: evaluate(*update_pose(R_, t_, step(damping), basis))

    state, cost = evaluate(R, t)
    R, t, _, _ = levenberg_marquardt(state, cost, linearize, max_iterations, 1e-8)
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
    J = sampson_jacobian(F, fundamental_derivatives(R, t, tangent_basis(t), K_inv), h1, h2)
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
    r = sampson_residuals_homogeneous(at.F, at.h1, at.h2)
    return robust_covariance(at.J_pose, r, loss, scale_px)


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

    Parameters
    ----------
    R, t : (3, 3), (3,) array_like
        Refined relative pose, ``x_cam2 = R x_cam1 + t`` (``|t| = 1``).
    pts1, pts2 : (N, 2) array_like
        Inlier pixels in images 1 and 2.
    K : (3, 3) array_like
        Intrinsics the pose was refined under (both views).
    loss : str, default "cauchy"
        Robust loss of the refinement.
    scale_px : float, default 0.5
        Its scale (px).

    Returns
    -------
    (5, 3) float64 ndarray
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
    J_theta = sampson_jacobian(at.F, np.stack(dF_theta), at.h1, at.h2)
    r = sampson_residuals_homogeneous(at.F, at.h1, at.h2)
    z = (r / scale_px) ** 2
    _, rho1, rho2 = robust_loss(z, loss)
    return nuisance_sensitivity(J_pose, J_theta, rho1 + 2.0 * rho2 * z)
