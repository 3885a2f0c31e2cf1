"""Multi-view bundle adjustment (H&Z section 18.1).

Cameras are world-to-camera poses ``x_cam = R X + t`` sharing one ``K``. The
unknowns are a rotation-vector update (``R <- exp([w]x) R``) and a translation
step per free camera, and the 3D points; the reference camera stays fixed (it
fixes the frame; the overall scale is held by the damping). Every observation
depends on one camera and one point, so Levenberg-Marquardt solves its normal
equations with the points eliminated (:mod:`scene3D.optim.schur`): one system of six
unknowns per camera, then a 3x3 solve per point.

One focal length shared by every view can be refined with the poses
(:func:`bundle_adjust_focal`, for photos without a calibration file): its unknown is
``log f`` (the principal point stays where ``K`` puts it, no skew, square pixels).
Every observation depends on it, fixed cameras' included, so it is a global
unknown of the normal equations (:mod:`scene3D.optim.schur`): one more row and column of
the reduced camera system, outside the per-point blocks. A prior
``(log f - log f_prior) / sigma_log`` (in units of the reprojection noise) holds it
where the views do not determine it; its standard deviation comes from the reduced
system with the cameras and points marginalised.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Callable, Sequence
from dataclasses import dataclass

import numpy as np

from ..geometry.camera import with_focal
from ..geometry.conventions import FloatArray, project_with_jacobian, rotations_from_vectors, skews
from .least_squares import levenberg_marquardt, reweighting, robust_cost
from .schur import global_information, normal_equations, solve_damped_global


@dataclass(frozen=True)
class Observations:
    """Which point is seen where: ``point[k]`` is seen by ``view[k]`` at pixel ``xy[k]``.

    Attributes
    ----------
    view : (O,) int
    point : (O,) int
    xy : (O, 2) float64
        Pixel coordinates (OpenCV convention).
    sigma : (O,) float64 or None
        Relative standard deviation of each observation's position (both coordinates):
        the adjustment minimises the residuals divided by it, the maximum-likelihood
        weighting when the observations' noise differs (SIFT keypoints are located
        less precisely the larger their scale). None: all equal (1).
    """

    view: np.ndarray
    point: np.ndarray
    xy: FloatArray
    sigma: FloatArray | None = None


def whitened_residuals(R: FloatArray, t: FloatArray, points3d: FloatArray, obs: Observations,
                       K: FloatArray) -> FloatArray:
    """:func:`reprojection_residuals` divided by each observation's ``obs.sigma`` ``(O, 2)``
    (the residuals themselves when ``sigma`` is None).

    Parameters
    ----------
    R : (V, 3, 3) ndarray
        World-to-camera rotations (``x_cam = R X + t``).
    t : (V, 3) ndarray
        World-to-camera translations.
    points3d : (P, 3) ndarray
        World points.
    obs : Observations
        ``O`` observations: view, point, pixel (OpenCV convention), optional sigma.
    K : (3, 3) ndarray
        Intrinsics shared by the views.

    Returns
    -------
    (O, 2) float64 ndarray
    """
    r = reprojection_residuals(R, t, points3d, obs, K)
    return r if obs.sigma is None else r / obs.sigma[:, None]


def whitened_reweighting(r: FloatArray, obs: Observations, loss: str,
                         scale_px: float) -> tuple[FloatArray, FloatArray]:
    """:func:`scene3D.optim.least_squares.reweighting` of the whitened residuals, its row
    scales divided by ``obs.sigma`` too: the whitened residuals' derivatives are the
    plain ones over it.

    Parameters
    ----------
    r : (O, 2) float64
        Whitened residuals (:func:`whitened_residuals`).
    obs : Observations
    loss, scale_px : str, float
        As in :func:`bundle_adjust`.

    Returns
    -------
    row_scale, reweighted : (O, 2) float64, (O, 2) float64
        As :func:`scene3D.optim.least_squares.reweighting` returns them.
    """
    row_scale, rw = reweighting(r, loss, scale_px)
    return (row_scale, rw) if obs.sigma is None else (row_scale / obs.sigma[:, None], rw)


def reprojection_residuals(
    R: FloatArray, t: FloatArray, points3d: FloatArray, obs: Observations, K: FloatArray
) -> FloatArray:
    """Reprojection errors ``(O, 2)`` in pixels (projection minus observation).

    Parameters
    ----------
    R : (V, 3, 3) ndarray
        World-to-camera rotations (``x_cam = R X + t``).
    t : (V, 3) ndarray
        World-to-camera translations.
    points3d : (P, 3) ndarray
        World points.
    obs : Observations
        ``O`` observations: view, point, pixel (OpenCV convention), optional sigma.
    K : (3, 3) ndarray
        Intrinsics shared by the views.

    Returns
    -------
    (O, 2) float64 ndarray
    """
    cam = np.einsum("oij,oj->oi", R[obs.view], points3d[obs.point]) + t[obs.view]
    pix = cam @ K.T
    return pix[:, :2] / pix[:, 2:3] - obs.xy


def reprojection_jacobians(
    R: FloatArray, t: FloatArray, points3d: FloatArray, obs: Observations, K: FloatArray
) -> tuple[FloatArray, FloatArray, FloatArray]:
    """Derivatives of :func:`reprojection_residuals` at each observation.

    Parameters
    ----------
    R : (V, 3, 3) ndarray
        World-to-camera rotations (``x_cam = R X + t``).
    t : (V, 3) ndarray
        World-to-camera translations.
    points3d : (P, 3) ndarray
        World points.
    obs : Observations
        ``O`` observations: view, point, pixel (OpenCV convention), optional sigma.
    K : (3, 3) ndarray
        Intrinsics shared by the views.


    Returns
    -------
    J_camera : (O, 2, 6)
        By the observing camera's update: the rotation vector ``w`` of
        ``R <- exp([w]x) R``, then the translation step.
    J_point : (O, 2, 3)
        By the point.
    J_log_focal : (O, 2, 1)
        By ``log f`` of ``K`` with both focal lengths scaled together (the principal
        point held): ``pixel - principal point``.
    """
    R_obs = R[obs.view]
    rotated = np.einsum("oij,oj->oi", R_obs, points3d[obs.point])
    pix, J = project_with_jacobian(rotated + t[obs.view], K)
    # d(R X + t) / d(w, dt) = [-[R X]x | I]; d(R X + t) / dX = R.
    J_camera = np.concatenate([J @ -skews(rotated), J], axis=2)
    J_point = J @ R_obs
    # pixel = f (x / z) + c: d pixel / d log f = f (x / z) = pixel - c (with fx = fy
    # scaled together; K[0, 1] = 0).
    J_log_focal = (pix - K[:2, 2])[:, :, None]
    return J_camera, J_point, J_log_focal


@dataclass(frozen=True)
class FocalAdjustment:
    """What :func:`bundle_adjust_focal` returns.

    Attributes
    ----------
    R, t, points3d : (V, 3, 3), (V, 3), (P, 3)
        Refined copies.
    K : (3, 3)
        The intrinsics with the refined focal length (principal point kept).
    focal_px : float
    sigma_log : float
        Standard deviation of ``log focal_px`` from the adjustment's covariance, the
        cameras and points marginalised, the prior included: the noise of the
        observations given the camera model.
    principal_point_sigma_log : float
        How far ``log focal_px`` would move were the principal point off by
        ``principal_point_shift_px`` in x, then in y (root of the sum of squares):
        the share of the guessed principal point, which ``sigma_log`` does not hold.
    noise_px : float
        Robust standard deviation of the final reprojection residuals (per coordinate;
        of the residuals divided by ``obs.sigma`` when the observations carry one).
    """

    R: FloatArray
    t: FloatArray
    points3d: FloatArray
    K: FloatArray
    focal_px: float
    sigma_log: float
    principal_point_sigma_log: float
    noise_px: float

    @property
    def total_sigma_log(self) -> float:
        """``sigma_log`` and ``principal_point_sigma_log`` combined (root of the sum of squares)."""
        return float(np.hypot(self.sigma_log, self.principal_point_sigma_log))


def robust_noise_px(r: FloatArray) -> float:
    """Robust standard deviation of residual coordinates (1.4826 MAD about zero).

    Parameters
    ----------
    r : (O, 2) float64
        Residuals in pixels (or whitened).

    Returns
    -------
    float
        At least 1e-6; 1 without residuals.
    """
    return float(max(1.4826 * np.median(np.abs(r)), 1e-6)) if r.size else 1.0


def _adjust(R: FloatArray, t: FloatArray, points3d: FloatArray, obs: Observations,
            K: FloatArray, fixed_view: int | Sequence[int], loss: str, scale_px: float,
            max_iterations: int, tolerance: float,
            focal_prior: tuple[float, float, float] | None
            ) -> tuple[FloatArray, FloatArray, FloatArray, float]:
    """Levenberg-Marquardt on the cameras, the points and, with ``focal_prior``
    ``(focal_px, sigma_log, noise_px)``, ``log f``. Returns R, t, X and the focal length."""
    num_points = len(points3d)
    free = np.setdiff1d(np.unique(obs.view), np.atleast_1d(np.asarray(fixed_view, dtype=int)))
    slot = np.full(len(R), -1, dtype=int)
    slot[free] = np.arange(len(free))
    camera = slot[obs.view]
    K = np.asarray(K, np.float64)
    if focal_prior is not None:
        prior_log, prior_sigma, prior_noise = (np.log(focal_prior[0]), focal_prior[1],
                                               focal_prior[2])
        prior_weight = prior_noise / prior_sigma  # the prior's row, in pixel units

    def evaluate(R_: FloatArray, t_: FloatArray, X_: FloatArray,
                 log_f: float) -> tuple[tuple, float]:
        K_ = K if focal_prior is None else with_focal(K, float(np.exp(log_f)))
        r_ = whitened_residuals(R_, t_, X_, obs, K_)
        cost = robust_cost(r_, loss, scale_px)
        if focal_prior is not None:
            cost += float((prior_weight * (log_f - prior_log)) ** 2)
        return (R_, t_, X_, log_f, r_), cost

    def linearize(state: tuple) -> Callable[[float], tuple]:
        R_, t_, X_, log_f, r_ = state
        K_ = K if focal_prior is None else with_focal(K, float(np.exp(log_f)))
        J_camera, J_point, J_focal = reprojection_jacobians(R_, t_, X_, obs, K_)
        row_scale, rw = whitened_reweighting(r_, obs, loss, scale_px)
        J_global = None if focal_prior is None else J_focal * row_scale[:, :, None]
        ne = normal_equations(J_camera * row_scale[:, :, None], camera,
                              J_point * row_scale[:, :, None], obs.point, rw, len(free),
                              num_points, J_global)
        if focal_prior is not None:
            ne = dataclasses.replace(
                ne, U_global=ne.U_global + prior_weight**2,
                g_global=ne.g_global + prior_weight**2 * (log_f - prior_log))

        def try_step(damping: float) -> tuple[tuple, float]:
            step_camera, step_global, step_point = solve_damped_global(ne, damping)
            R_new, t_new = R_.copy(), t_.copy()
            R_new[free] = rotations_from_vectors(step_camera[:, :3]) @ R_[free]
            t_new[free] = t_[free] + step_camera[:, 3:]
            log_new = log_f + float(step_global[0]) if focal_prior is not None else log_f
            return evaluate(R_new, t_new, X_ + step_point, log_new)

        return try_step

    log_f0 = float(np.log(K[0, 0]))
    state, cost = evaluate(np.array(R, np.float64), np.array(t, np.float64),
                           np.asarray(points3d, np.float64), log_f0)
    R, t, X, log_f, _ = levenberg_marquardt(state, cost, linearize, max_iterations,
                                             tolerance)
    return R, t, X, float(np.exp(log_f))


def bundle_adjust(
    R: FloatArray,
    t: FloatArray,
    points3d: FloatArray,
    obs: Observations,
    K: FloatArray,
    fixed_view: int | Sequence[int],
    loss: str = "soft_l1",
    scale_px: float = 1.0,
    max_iterations: int = 50,
    tolerance: float = 1e-10,
) -> tuple[FloatArray, FloatArray, FloatArray]:
    """Refine all observed cameras but ``fixed_view`` and all points.

    Parameters
    ----------
    R, t : (V, 3, 3), (V, 3)
        World-to-camera poses (views never observed are left as they are).
    points3d : (P, 3)
        World points.
    obs : Observations
        The measurements; only the cameras and points they mention take part (a local
        adjustment passes the observations of the points it refines).
    K : (3, 3)
        Intrinsics shared by every view.
    fixed_view : int or sequence of int
        Cameras held fixed (they fix the frame; with one fixed camera the scale is held
        by the damping). Observations by fixed cameras still constrain the points.
    loss, scale_px : str, float
        Robust loss (``"linear"``, ``"huber"``, ``"soft_l1"``, ``"cauchy"``, as in
        scipy, applied to each pixel coordinate) and its scale in pixels.
    max_iterations : int
        Levenberg-Marquardt iterations at most; it stops earlier once a step
        gains less than ``tolerance`` of the cost.

    Returns
    -------
    R, t, points3d
        Refined copies.
    """
    R, t, X, _ = _adjust(R, t, points3d, obs, K, fixed_view, loss, scale_px, max_iterations,
                         tolerance, None)
    return R, t, X


def bundle_adjust_focal(
    R: FloatArray,
    t: FloatArray,
    points3d: FloatArray,
    obs: Observations,
    K: FloatArray,
    fixed_view: int | Sequence[int],
    prior_focal_px: float,
    prior_sigma_log: float,
    loss: str = "soft_l1",
    scale_px: float = 1.0,
    max_iterations: int = 50,
    tolerance: float = 1e-10,
    principal_point_shift_px: float = 0.0,
) -> FocalAdjustment:
    """:func:`bundle_adjust` with one focal length shared by every view refined too.

    Parameters
    ----------
    R, t, points3d, obs, fixed_view, loss, scale_px, max_iterations, tolerance
        As in :func:`bundle_adjust`.
    K : (3, 3)
        Starting intrinsics: ``K[0, 0]`` (= ``K[1, 1]``) is where ``f`` starts; the
        principal point is held.
    prior_focal_px, prior_sigma_log : float
        The prior ``log f ~ N(log prior_focal_px, prior_sigma_log^2)`` (EXIF or the
        default, :class:`scene3D.geometry.intrinsics_prior.FocalPrior`, at the working size). Its
        residual is measured in units of the reprojection noise (the residuals' robust
        standard deviation, from the start; when the adjusted residuals turn out much
        smaller, the adjustment runs again with theirs), so it weighs as one
        observation of that noise would.
    principal_point_shift_px : float
        Assumed standard deviation of the principal point from where ``K`` puts it, for
        :attr:`FocalAdjustment.principal_point_sigma_log` (0: not computed).

    Returns
    -------
    FocalAdjustment
    """
    K = np.asarray(K, np.float64)
    if not (np.isfinite(prior_focal_px) and prior_focal_px > 0 and prior_sigma_log > 0):
        raise ValueError(f"the focal prior must be positive, got {prior_focal_px} px "
                         f"+-{prior_sigma_log} (log)")
    R, t = np.asarray(R, np.float64), np.asarray(t, np.float64)
    X = np.asarray(points3d, np.float64)
    noise = robust_noise_px(whitened_residuals(R, t, X, obs, K))
    # The prior's weight needs the noise of the converged residuals; a start far off
    # inflates it (and the prior's pull with it), so adjust again once it is known.
    for _ in range(3):
        R, t, X, focal = _adjust(R, t, X, obs, K, fixed_view, loss, scale_px, max_iterations,
                                 tolerance, (prior_focal_px, prior_sigma_log, noise))
        K = with_focal(K, focal)
        settled = robust_noise_px(whitened_residuals(R, t, X, obs, K))
        if settled > 0.5 * noise:
            break
        noise = settled
    K_new = K
    sigma, pp_sigma, noise = focal_uncertainty(R, t, X, obs, K_new, fixed_view, prior_focal_px,
                                               prior_sigma_log, loss, scale_px,
                                               principal_point_shift_px)
    return FocalAdjustment(R, t, X, K_new, focal, sigma, pp_sigma, noise)


def focal_uncertainty(
    R: FloatArray, t: FloatArray, points3d: FloatArray, obs: Observations, K: FloatArray,
    fixed_view: int | Sequence[int], prior_focal_px: float, prior_sigma_log: float,
    loss: str = "soft_l1", scale_px: float = 1.0, principal_point_shift_px: float = 0.0,
) -> tuple[float, float, float]:
    """How well the observations determine ``log f`` of ``K`` at an adjusted state.

    The normal equations of the cameras, the points and ``(log f, cx, cy)`` (the robust
    loss's weights, residuals in units of their robust standard deviation, the prior
    on ``log f`` added) are reduced to the three global unknowns, cameras and points
    marginalised (:func:`scene3D.optim.schur.global_information`).

    Parameters
    ----------
    R : (V, 3, 3) ndarray
        World-to-camera rotations (``x_cam = R X + t``).
    t : (V, 3) ndarray
        World-to-camera translations.
    points3d : (P, 3) ndarray
        World points.
    obs : Observations
        ``O`` observations: view, point, pixel (OpenCV convention), optional sigma.
    K : (3, 3) ndarray
        Intrinsics shared by the views.
    fixed_view : int or sequence of int
        Views held fixed (the gauge).
    prior_focal_px : float
        Prior focal length (px).
    prior_sigma_log : float
        Prior standard deviation of ``log f``.
    loss : str, default "soft_l1"
        Robust loss (:func:`scene3D.optim.least_squares.robust_loss`).
    scale_px : float, default 1.0
        Its scale (px).
    principal_point_shift_px : float, default 0.0
        Assumed error of the principal point (px).


    Returns
    -------
    sigma_log : float
        Standard deviation of ``log f`` (the principal point known).
    principal_point_sigma_log : float
        ``|d log f / d c| * principal_point_shift_px`` over x and y (root of the sum
        of squares): the shift of the estimate when the principal point is off
        (``H_ff^-1 H_fc``, the estimate's response to a held parameter).
    noise_px : float
        The residuals' robust standard deviation (divided by ``obs.sigma`` when given).
    """
    free = np.setdiff1d(np.unique(obs.view), np.atleast_1d(np.asarray(fixed_view, dtype=int)))
    slot = np.full(len(R), -1, dtype=int)
    slot[free] = np.arange(len(free))
    r = whitened_residuals(R, t, points3d, obs, K)
    noise = robust_noise_px(r)
    J_camera, J_point, J_focal = reprojection_jacobians(R, t, points3d, obs, K)
    row_scale, rw = whitened_reweighting(r, obs, loss, scale_px)
    J_pp = np.broadcast_to(np.eye(2), (len(r), 2, 2))
    J_global = np.concatenate([J_focal, J_pp], axis=2) * row_scale[:, :, None]
    ne = normal_equations(J_camera * row_scale[:, :, None], slot[obs.view],
                          J_point * row_scale[:, :, None], obs.point, rw, len(free),
                          len(points3d), J_global)
    info = global_information(ne) / noise**2
    info[0, 0] += 1.0 / prior_sigma_log**2
    # The principal point held (as it is): the estimate responds to its offset by
    # -H_ff^-1 H_fc (cameras and points marginalised).
    response = info[0, 1:] / info[0, 0]
    pp = float(np.linalg.norm(response) * principal_point_shift_px)
    return float(1.0 / np.sqrt(info[0, 0])), pp, noise
