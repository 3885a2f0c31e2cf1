"""First-order uncertainty of a two-view pose.

The pose is written in the parametrisation of :mod:`scene3D.optim.parametrisation`
(``x = (w, d)``: a rotation vector in the camera-2 frame and a step tangent to the
unit translation). A pose covariance ``(5, 5)`` is the covariance of ``x``: rows and
columns 0-2 the rotation, 3-4 the translation direction (with the basis
:func:`scene3D.optim.parametrisation.tangent_basis` it refers to). The covariances of
triangulated points are in :mod:`scene3D.optim.point_uncertainty`; both modules'
names are re-exported here, their old home.

Angular sigmas and bounds
-------------------------
``rotation_sigma_deg`` and ``translation_sigma_deg`` are the 1-sigma angles along
the worst direction: the square root of the largest eigenvalue of the rotation
block ``(3, 3)`` and of the direction block ``(2, 2)``, in degrees. An error lies
within the predicted 90 % bound when its Mahalanobis distance under the block is
within the chi-square quantile of 3 (rotation) or 2 (direction) degrees of
freedom (:func:`pose_error_chi2`); the angle of such an error is at most
``sqrt(quantile) * sigma`` (:func:`angular_bound_deg`).

The covariance itself is the M-estimator's sandwich (Huber, *Robust Statistics*,
1981, section 7.6) with a leverage correction (HC3), computed from the Jacobian of
the residuals at the optimum, the robust loss's weights and the residuals
themselves (:func:`sandwich_covariance`); :mod:`scene3D.optim.refinement` builds it for the
robust Sampson refinement (:func:`scene3D.optim.refinement.relative_pose_covariance`)
and the focal-length fit.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import NamedTuple

import numpy as np
from numpy.typing import ArrayLike

from ..geometry.conventions import FloatArray, median
from .parametrisation import (  # noqa: F401  (re-exported: their old home)
    pose_error_coordinates,
    rotation_vector,
    tangent_basis,
    update_pose,
)
from .point_uncertainty import depth_sigmas, point_covariances  # noqa: F401  (re-exported)

CHI2_90 = {2: 4.605170185988091, 3: 6.251388631170325}
"""90 % quantiles of the chi-square distribution with 2 and 3 degrees of freedom: the
Mahalanobis bounds of a direction error (2 dof) and of a rotation error (3 dof)."""

CHI2_99_POSE = 15.086272469388987
"""The 99 % quantile of chi-squared with 5 degrees of freedom, those of a relative pose:
a pose whose :func:`pose_difference_chi2` exceeds it lies outside the region that the
covariance allows."""


def sandwich_covariance(J: FloatArray, influence: FloatArray,
                        slope: FloatArray) -> FloatArray:
    """Covariance ``(k, k)`` of an M-estimate from its Jacobian and robust residuals.

    For a cost ``sum rho(r_i)`` minimised over ``k`` parameters, with ``psi`` the
    loss's influence function (``rho'`` by ``r``) and ``psi'`` its slope, the
    first-order covariance is the sandwich ``H^-1 M H^-1`` with
    ``H = sum psi'_i J_i^T J_i`` (the cost's Gauss-Newton Hessian, the loss's curvature
    included) and ``M = sum psi_i^2 J_i^T J_i`` (the spread of the gradient; Huber,
    *Robust Statistics*, 1981, section 7.6). It needs no noise model: the residuals
    measure the noise, outliers are discounted by the loss, and noise that differs
    between rows is allowed for. Each row's term is divided by ``(1 - h_i)^2``, its
    leverage ``h_i = psi'_i J_i H^-1 J_i^T`` (clipped to [0, 0.9]): the jackknife-like
    correction HC3 (MacKinnon and White, 1985), which accounts for the degrees of
    freedom the fit used (the leverages sum to ``k``) and for rows that pull the fit
    towards themselves, such as an outlier that passed as an inlier. Least squares
    (``psi = r``, ``psi' = 1``) with alike residuals gives about
    ``(J^T J)^-1 sum r^2 / (n - k)``.

    Parameters
    ----------
    J : (n, k) array
        Jacobian of the residuals at the optimum.
    influence, slope : (n,) array
        ``psi(r_i)`` and ``psi'(r_i)`` in the residuals' units.

    Returns
    -------
    (k, k) float64
        Infinite everywhere when ``H`` is not positive definite or ``n <= k``: the
        data do not determine the parameters.
    """
    n, k = J.shape
    if n <= k:
        return np.full((k, k), np.inf)
    H = J.T @ (slope[:, None] * J)
    try:
        np.linalg.cholesky(H)
        H_inv = np.linalg.inv(H)
    except np.linalg.LinAlgError:
        return np.full((k, k), np.inf)
    leverage = np.maximum(slope, 0.0) * np.einsum("ij,jk,ik->i", J, H_inv, J)
    weights = influence**2 / (1.0 - np.clip(leverage, 0.0, 0.9)) ** 2
    cov = H_inv @ (J.T @ (weights[:, None] * J)) @ H_inv
    return 0.5 * (cov + cov.T)


def nuisance_sensitivity(J_pose: FloatArray, J_nuisance: FloatArray,
                         slope: FloatArray) -> FloatArray:
    """How the optimum of a robust fit moves with parameters held fixed in it.

    A cost ``sum rho(r_i(x, theta))`` minimised over ``x`` (``k`` parameters) with
    ``theta`` (``m`` nuisance parameters, such as the intrinsics) held at an assumed
    value has its optimum at ``x*(theta)``; to first order (implicit function
    theorem) ``dx*/dtheta = -H_xx^-1 H_xtheta`` with the Gauss-Newton blocks
    ``H_xx = sum psi'_i J_x,i^T J_x,i`` and ``H_xtheta = sum psi'_i J_x,i^T J_theta,i``
    (the loss's curvature included, as in :func:`sandwich_covariance`).

    Parameters
    ----------
    J_pose : (n, k) array
        Jacobian of the residuals by the fitted parameters, at the optimum.
    J_nuisance : (n, m) array
        Jacobian of the residuals by the parameters held fixed.
    slope : (n,) array
        ``psi'(r_i)``.

    Returns
    -------
    (k, m) float64
        ``dx*/dtheta``; infinite when ``H_xx`` is not positive definite.
    """
    H = J_pose.T @ (slope[:, None] * J_pose)
    H_cross = J_pose.T @ (slope[:, None] * J_nuisance)
    try:
        np.linalg.cholesky(H)
        return -np.linalg.solve(H, H_cross)
    except np.linalg.LinAlgError:
        return np.full((J_pose.shape[1], J_nuisance.shape[1]), np.inf)


def marginal_covariance(covariance: ArrayLike, sensitivity: ArrayLike,
                        nuisance_covariance: ArrayLike) -> FloatArray:
    """Covariance ``(k, k)`` of a fit once the uncertainty of what it held fixed is added.

    ``covariance`` ``(k, k)`` is the fit's own, conditional on the nuisance
    parameters ``theta`` (``m``) it assumed; ``sensitivity`` ``(k, m)`` how its
    optimum moves with them (:func:`nuisance_sensitivity`); ``nuisance_covariance``
    ``(m, m)`` how well they are known. To first order, with the assumed ``theta``'s
    error independent of the fit's noise, the marginal covariance is
    ``C + S Sigma S^T``. For a parameter estimated from the same residuals (the
    focal length fitted with the pose) and known to its own sandwich variance, this
    is the ``(k, k)`` block of the joint ``(k + m)`` covariance (exactly, when the
    sandwich reduces to ``H^-1``); a larger variance (a jackknife's, or a prior's
    when the data do not determine it) widens it accordingly.

    Parameters
    ----------
    covariance : (k, k) array_like
        The fit's conditional covariance.
    sensitivity : (k, m) array_like
        How the optimum moves with the nuisance parameters.
    nuisance_covariance : (m, m) array_like
        Their covariance.

    Returns
    -------
    (k, k) float64 ndarray
        Infinite when an input is not finite.
    """
    C = np.asarray(covariance, dtype=np.float64)
    S = np.asarray(sensitivity, dtype=np.float64)
    Sigma = np.asarray(nuisance_covariance, dtype=np.float64)
    if not (np.all(np.isfinite(C)) and np.all(np.isfinite(S)) and np.all(np.isfinite(Sigma))):
        return np.full(C.shape, np.inf)
    out = C + S @ Sigma @ S.T
    return 0.5 * (out + out.T)


class TruncatedNoise(NamedTuple):
    """The keypoint noise behind inliers that a threshold cut (:func:`truncated_noise`).

    Attributes
    ----------
    sigma_px : float
        Standard deviation of the noise, per coordinate, before the cut (infinite
        when no Gaussian explains the distances).
    cut_share : float
        Share of the matches that fit the pose which lie beyond the threshold.
    variance_factor : float
        Variance of the inliers' distances over ``sigma_px^2``: 1 without a cut,
        0 when the noise is unknown.
    """

    sigma_px: float
    cut_share: float
    variance_factor: float


def truncated_noise(distances: ArrayLike, threshold_px: float) -> TruncatedNoise:
    """How much of the keypoint noise an inlier threshold cut off.

    With Gaussian noise of ``sigma`` px on each coordinate, a Sampson distance is
    ``N(0, sigma^2)`` to first order; the inliers' distances ``(N,)`` are those within
    ``threshold_px``, so they follow that normal cut at ``c = threshold_px / sigma``.
    Their median ``m`` solves ``erf(m / (sigma sqrt 2)) = erf(c / sqrt 2) / 2``, which
    gives ``sigma`` (bisection; ``1.4826 m`` when the cut is far out, as
    :func:`scene3D.twoview.essential_fit.noise_sigma_px` assumes); the share cut is
    ``1 - erf(c / sqrt 2)`` and the cut distances' variance is ``sigma^2`` times
    ``1 - 2 c phi(c) / erf(c / sqrt 2)`` (``phi`` the normal density). A covariance
    measured from the cut residuals is that factor too small
    (``scene3D.twoview.core.pose_covariance`` divides by it). When the median is half
    the threshold or more (distances spread evenly up to it: the threshold holds no
    recognisable part of a Gaussian), the noise is unknown: ``sigma_px`` infinite,
    ``cut_share`` 1, ``variance_factor`` 0; likewise with fewer than six distances.

    Parameters
    ----------
    distances : (N,) array_like
        Sampson distances (px); those beyond ``threshold_px`` are ignored.
    threshold_px : float
        The inlier threshold (px).

    Returns
    -------
    TruncatedNoise
    """
    d = np.abs(np.asarray(distances, dtype=np.float64).ravel())
    d = d[d <= threshold_px]
    if len(d) < 6 or threshold_px <= 0:
        return TruncatedNoise(math.inf, 1.0, 0.0)
    m = median(d)  # not np.median, which imports numpy.ma (18 ms) on its first call
    if m >= 0.5 * threshold_px:
        return TruncatedNoise(math.inf, 1.0, 0.0)
    if m <= 0.0:
        return TruncatedNoise(0.0, 0.0, 1.0)

    def excess(sigma: float) -> float:  # decreasing in sigma, positive below the root
        return (math.erf(m / (sigma * math.sqrt(2)))
                - 0.5 * math.erf(threshold_px / (sigma * math.sqrt(2))))

    low, high = m, 1.4826 * m  # excess(m) > 0: the root lies above m
    while excess(high) > 0:
        low, high = high, 2.0 * high
    for _ in range(60):
        mid = math.sqrt(low * high)
        low, high = (mid, high) if excess(mid) > 0 else (low, mid)
    sigma = math.sqrt(low * high)
    c = threshold_px / sigma
    inside = math.erf(c / math.sqrt(2))
    density = math.exp(-0.5 * c * c) / math.sqrt(2.0 * math.pi)
    return TruncatedNoise(sigma, 1.0 - inside, max(1.0 - 2.0 * c * density / inside, 0.0))


def largest_sigma_deg(block: FloatArray) -> float:
    """Square root of the largest eigenvalue of a covariance block (radians^2), in degrees.

    The 1-sigma angle along the worst direction; infinite when the block is not finite.

    Parameters
    ----------
    block : (k, k) ndarray
        Covariance block of angles (radians^2).

    Returns
    -------
    float
    """
    if not np.all(np.isfinite(block)):
        return float("inf")
    return float(np.degrees(np.sqrt(max(np.linalg.eigvalsh(block)[-1], 0.0))))


@dataclass(frozen=True)
class PoseUncertainty:
    """The first-order uncertainty of a relative pose.

    In the parametrisation of :mod:`scene3D.optim.parametrisation`.

    Attributes
    ----------
    covariance : (5, 5) float64
        Covariance of ``(w, d)`` in radians^2 (infinite when the matches do not
        determine the pose).
    basis : (2, 3) float64
        :func:`tangent_basis` of the pose's ``t``: the directions of ``d``.
    noise_sigma_px : float
        Robust standard deviation of the keypoint noise measured on the inliers
        (:func:`scene3D.twoview.essential_fit.noise_sigma_px`), per coordinate.
    noise_cut_share : float
        Share of the matches that fit the pose which the inlier threshold cut off
        (:func:`truncated_noise`); the covariance allows for the cut.
    """

    covariance: FloatArray
    basis: FloatArray
    noise_sigma_px: float = float("nan")
    noise_cut_share: float = 0.0

    @property
    def rotation_sigma_deg(self) -> float:
        """1-sigma rotation angle (degrees) along the worst axis."""
        return largest_sigma_deg(self.covariance[:3, :3])

    @property
    def translation_sigma_deg(self) -> float:
        """1-sigma angle (degrees) of the translation direction along the worst axis."""
        return largest_sigma_deg(self.covariance[3:, 3:])


def angular_bound_deg(sigma_deg: float, dof: int, probability: float = 0.9) -> float:
    """An angle (degrees) that the error stays below with at least ``probability``.

    The ``probability`` ellipsoid of a Gaussian error with ``dof`` degrees of freedom
    (``chi2_dof(probability)`` in Mahalanobis distance) lies inside the ball of radius
    ``sqrt(chi2) * sigma``, ``sigma`` along the worst axis (:func:`largest_sigma_deg`).
    Only ``probability = 0.9`` is tabulated (:data:`CHI2_90`).

    Parameters
    ----------
    sigma_deg : float
        1-sigma angle along the worst axis (deg).
    dof : int
        Degrees of freedom, 2 or 3.
    probability : float, default 0.9
        Only 0.9 is tabulated.

    Returns
    -------
    float

    Raises
    ------
    ValueError
        For another ``probability`` or ``dof``.
    """
    if probability != 0.9 or dof not in CHI2_90:
        raise ValueError(f"only the 90 % bound of 2 or 3 dof is tabulated, got "
                         f"probability={probability}, dof={dof}")
    return float(np.sqrt(CHI2_90[dof]) * sigma_deg)


def pose_error_chi2(R_est: ArrayLike, t_est: ArrayLike, R_true: ArrayLike,
                    t_true: ArrayLike, covariance: FloatArray) -> tuple[float, float]:
    """Mahalanobis distances (squared) of a pose's error under its predicted covariance.

    ``covariance`` ``(5, 5)`` is the estimate's (:mod:`scene3D.optim.parametrisation`, basis
    :func:`tangent_basis` of ``t_est``). Returns ``(rotation, direction)``: the
    rotation error's under the ``(3, 3)`` block, to compare with a chi-square of 3
    degrees of freedom, and the translation direction's under the ``(2, 2)`` block
    (2 degrees of freedom). The error is within the predicted 90 % bound when each
    is at most :data:`CHI2_90` of its degrees of freedom.

    Parameters
    ----------
    R_est, t_est : (3, 3), (3,) array_like
        Estimated relative pose, ``x_cam2 = R x_cam1 + t``.
    R_true, t_true : (3, 3), (3,) array_like
        True pose.
    covariance : (5, 5) array_like
        The estimate's covariance.

    Returns
    -------
    rotation, direction : float
    """
    w, d = pose_error_coordinates(R_est, t_est, R_true, t_true)
    covariance = np.asarray(covariance, dtype=np.float64)
    out = []
    for err, block in ((w, covariance[:3, :3]), (d, covariance[3:, 3:])):
        if not (np.all(np.isfinite(block)) and np.all(np.isfinite(err))):
            out.append(0.0 if np.all(np.isfinite(err)) else float("inf"))
            continue
        try:
            out.append(float(err @ np.linalg.solve(block, err)))
        except np.linalg.LinAlgError:
            out.append(float("inf"))
    return out[0], out[1]


def pose_difference_chi2(R: ArrayLike, t: ArrayLike, R_other: ArrayLike, t_other: ArrayLike,
                         covariance: FloatArray) -> float:
    """Mahalanobis distance (squared, 5 degrees of freedom) of another pose from ``R, t``
    under the ``(5, 5)`` covariance of ``R, t`` (:mod:`scene3D.optim.parametrisation`, basis
    :func:`tangent_basis` of ``t``), rotation and translation direction jointly; compare
    with :data:`CHI2_99_POSE`. 0 when the covariance is not finite (no region to leave).

    Parameters
    ----------
    R, t : (3, 3), (3,) array_like
        The pose, ``x_cam2 = R x_cam1 + t``.
    R_other, t_other : (3, 3), (3,) array_like
        The other pose.
    covariance : (5, 5) array_like
        Covariance of ``R, t``.

    Returns
    -------
    float
    """
    covariance = np.asarray(covariance, dtype=np.float64)
    if not np.all(np.isfinite(covariance)):
        return 0.0
    w, d = pose_error_coordinates(R, t, R_other, t_other)
    e = np.concatenate([w, d])
    try:
        return float(e @ np.linalg.solve(covariance, e))
    except np.linalg.LinAlgError:
        return 0.0
