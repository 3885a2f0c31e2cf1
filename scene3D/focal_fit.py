"""The focal-length check: the pose refined with a common factor on the focal lengths.

:func:`fit_focal_scale` refines the pose with a common factor on the focal lengths, to
tell whether the calibration fits the matches: the robust Sampson refinement of
:func:`scene3D.refinement.refine_relative_pose` with one more unknown. Its standard
deviation and the pose's covariance
(:func:`scene3D.refinement.relative_pose_covariance`) share one sandwich estimate
(:func:`scene3D.uncertainty.sandwich_covariance`).

``t`` ends on the unit sphere, since a two-view translation has no scale. Frames as in
:mod:`scene3D.geometry`: ``x_cam2 = R x_cam1 + t``.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import NamedTuple

import numpy as np
from numpy.typing import ArrayLike

from .geometry import FloatArray, skew, to_homogeneous
from .refinement import (
    _damped_steps,
    _fundamental_derivatives,
    _levenberg_marquardt,
    _robust_cost,
    _robust_covariance,
    _sampson,
    _sampson_jacobian,
    _update_pose,
)
from .uncertainty import tangent_basis


def _scaled_fundamental(R: FloatArray, t: FloatArray, log_s: float,
                        K_inv: FloatArray) -> FloatArray:
    """``F = K_s^-T [t]x R K_s^-1`` for ``K_s = K diag(s, s, 1)``, ``s = exp(log_s)``."""
    Ks_inv = np.diag([np.exp(-log_s), np.exp(-log_s), 1.0]) @ K_inv
    return Ks_inv.T @ skew(t) @ R @ Ks_inv


def _focal_fundamental_derivatives(R: FloatArray, t: FloatArray, log_s: float,
                                   basis: FloatArray, K_inv: FloatArray) -> FloatArray:
    """``dF / dx`` ``(6, 3, 3)`` of :func:`_scaled_fundamental`: the pose step of
    :func:`scene3D.refinement._update_pose` (5), then ``log s``.

    ``d(K_s^-1) / d(log s) = -P K_s^-1`` with ``P = diag(1, 1, 0)``.
    """
    Ks_inv = np.diag([np.exp(-log_s), np.exp(-log_s), 1.0]) @ K_inv
    E = skew(t) @ R
    P = np.diag([1.0, 1.0, 0.0])
    d_log_s = -Ks_inv.T @ (P @ E + E @ P) @ Ks_inv
    return np.concatenate([_fundamental_derivatives(R, t, basis, Ks_inv), d_log_s[None]])


class FocalFit(NamedTuple):
    """What :func:`fit_focal_scale` found.

    Attributes
    ----------
    scale : float
        The focal length that best explains the matches, as a multiple of the
        calibration's (1: the calibration fits).
    sigma_log : float
        First-order standard deviation of ``log(scale)`` (inf when the matches do
        not determine the focal length, e.g. without rotation).
    R, t : (3, 3), (3,) float64
        The pose refined with it (``|t| = 1``).
    """

    scale: float
    sigma_log: float
    R: FloatArray
    t: FloatArray


def fit_focal_scale(
    R: ArrayLike,
    t: ArrayLike,
    pts1: ArrayLike,
    pts2: ArrayLike,
    K: ArrayLike,
    loss: str = "cauchy",
    scale_px: float = 0.5,
    max_iterations: int = 30,
    initial_scale: float = 1.0,
) -> FocalFit:
    """Check a calibration against the matches: the focal length they call for.

    Refines the pose together with a common factor ``s`` on both focal lengths
    (``K_s = K diag(s, s, 1)``: the principal point and aspect kept), minimising
    the robust Sampson distances of the inlier correspondences as
    :func:`scene3D.refinement.refine_relative_pose` does, from ``s = initial_scale``.
    Two views with rotation and depth determine ``s``; a calibration for another
    camera, lens or zoom shows as ``s`` far from 1 with a small ``sigma_log``.

    Parameters
    ----------
    R, t : (3, 3), (3,) array_like
        Pose found with ``K``, ``x_cam2 = R x_cam1 + t``.
    pts1, pts2 : (N, 2) array_like
        Inlier pixels (N >= 6).
    K : (3, 3) array_like
        The calibration's intrinsics (both views).
    loss, scale_px : str, float
        Robust loss and its scale in pixels, as for
        :func:`scene3D.refinement.refine_relative_pose`.

    Returns
    -------
    FocalFit
    """
    R = np.asarray(R, dtype=np.float64)
    t = np.asarray(t, dtype=np.float64).reshape(3)
    t = t / np.linalg.norm(t)
    h1 = to_homogeneous(np.asarray(pts1, dtype=np.float64))
    h2 = to_homogeneous(np.asarray(pts2, dtype=np.float64))
    K_inv = np.linalg.inv(np.asarray(K, dtype=np.float64))

    def evaluate(R_: FloatArray, t_: FloatArray, log_s: float) -> tuple[tuple, float]:
        F_ = _scaled_fundamental(R_, t_, log_s, K_inv)
        r_ = _sampson(F_, h1, h2)
        return (R_, t_, log_s, F_, r_), _robust_cost(r_, loss, scale_px)

    def jacobian(state: tuple) -> tuple[FloatArray, FloatArray]:
        R_, t_, log_s, F_, _ = state
        basis = tangent_basis(t_)
        dF = _focal_fundamental_derivatives(R_, t_, log_s, basis, K_inv)
        return _sampson_jacobian(F_, dF, h1, h2), basis

    def linearize(state: tuple) -> Callable[[float], tuple]:
        R_, t_, log_s, _, r_ = state
        J, basis = jacobian(state)
        step = _damped_steps(J, r_, loss, scale_px)

        def try_step(damping: float) -> tuple[tuple, float]:
            dx = step(damping)
            return evaluate(*_update_pose(R_, t_, dx[:5], basis), log_s + dx[5])
        return try_step

    state, cost = evaluate(R, t, float(np.log(initial_scale)))
    state = _levenberg_marquardt(state, cost, linearize, max_iterations, 1e-10)
    log_s, r = state[2], state[4]
    # The same first-order covariance as the pose's (refinement.relative_pose_covariance).
    variance = _robust_covariance(jacobian(state)[0], r, loss, scale_px)[5, 5]
    sigma_log = float(np.sqrt(variance)) if 0 < variance < np.inf else np.inf
    return FocalFit(float(np.exp(log_s)), sigma_log, state[0], state[1])
