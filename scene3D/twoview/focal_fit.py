"""The focal-length checks: the pose refined with a factor on the focal lengths.

:func:`fit_focal_scale` refines the pose with a common factor on the focal lengths, to
tell whether the calibration fits the matches: the robust Sampson refinement of
:func:`scene3D.optim.refinement.refine_relative_pose` with one more unknown.
:func:`fit_focal_ratio` does the same with image 2's focal length against image 1's,
to tell whether one calibration fits both photos (not two zoom settings, nor one photo
cropped and enlarged). Its standard
deviation and the pose's covariance
(:func:`scene3D.optim.refinement.relative_pose_covariance`) share one sandwich estimate
(:func:`scene3D.optim.uncertainty.sandwich_covariance`).

``t`` ends on the unit sphere, since a two-view translation has no scale. Frames as in
:mod:`scene3D.geometry`: ``x_cam2 = R x_cam1 + t``.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np
from numpy.typing import ArrayLike

from ..geometry.conventions import FloatArray, skew, to_homogeneous
from ..geometry.epipolar import (
    fundamental_derivatives,
    sampson_jacobian,
    sampson_residuals,
    sampson_residuals_homogeneous,
)
from ..optim.refinement import refine_pose_and_parameter

#: How each check scales the two focal lengths: ``log s1 = w1 x``, ``log s2 = w2 x`` for
#: the fitted unknown ``x``. A common factor; image 2's against image 1's, half each way
#: (``s2 / s1 = exp(x)``, the same for the pair taken in either order).
COMMON = (1.0, 1.0)
RATIO = (-0.5, 0.5)
#: The fit does not step beyond this factor either way (``|x| <= log(100)``): a focal
#: length a hundred times off is no calibration a little off, and on matches that fit no
#: geometry the steps ran on until ``exp`` overflowed.
MAX_LOG_SCALE = float(np.log(100.0))


def _scaled_inverses(x: float, weights: tuple[float, float],
                     K_inv: FloatArray) -> tuple[FloatArray, FloatArray]:
    """``K_i^-1`` of ``K_i = K diag(s_i, s_i, 1)``, ``log s_i = w_i x``, for both images."""
    return tuple(np.diag([np.exp(-w * x), np.exp(-w * x), 1.0]) @ K_inv for w in weights)


def scaled_fundamental(R: FloatArray, t: FloatArray, x: float, weights: tuple[float, float],
                       K_inv: FloatArray) -> FloatArray:
    """``F = K_2^-T [t]x R K_1^-1`` (:func:`_scaled_inverses`).

    Parameters
    ----------
    R, t : (3, 3), (3,) array_like
        Relative pose ``x_cam2 = R x_cam1 + t`` (``|t| = 1``: the scale is unknown).
    x : float
        Focal-length parameter: ``log s_i = w_i x`` scales image ``i``'s focal length.
    weights : (float, float)
        Shares of ``x`` in images 1 and 2.
    K_inv : (3, 3) array_like
        Inverse of the calibration's intrinsics.

    Returns
    -------
    (3, 3) float64 ndarray
    """
    K1_inv, K2_inv = _scaled_inverses(x, weights, K_inv)
    return K2_inv.T @ skew(t) @ R @ K1_inv


def focal_fundamental_derivatives(R: FloatArray, t: FloatArray, x: float,
                                  weights: tuple[float, float], basis: FloatArray,
                                  K_inv: FloatArray) -> FloatArray:
    """``dF / dx`` ``(6, 3, 3)`` of :func:`scaled_fundamental`: the pose step of
    :func:`scene3D.optim.uncertainty.update_pose` (5), then ``x``.

    ``d(K_i^-1) / dx = -w_i P K_i^-1`` with ``P = diag(1, 1, 0)``.

    Parameters
    ----------
    R, t : (3, 3), (3,) array_like
        Relative pose ``x_cam2 = R x_cam1 + t`` (``|t| = 1``: the scale is unknown).
    x : float
        Focal-length parameter: ``log s_i = w_i x`` scales image ``i``'s focal length.
    weights : (float, float)
        Shares of ``x`` in images 1 and 2.
    basis : (2, 3) array_like
        Orthonormal rows spanning the tangent plane of ``t``
        (:func:`scene3D.optim.uncertainty.tangent_basis`).
    K_inv : (3, 3) array_like
        Inverse of the calibration's intrinsics.
    """
    K1_inv, K2_inv = _scaled_inverses(x, weights, K_inv)
    E = skew(t) @ R
    P = np.diag([1.0, 1.0, 0.0])
    d_x = -K2_inv.T @ (weights[1] * P @ E + weights[0] * E @ P) @ K1_inv
    return np.concatenate([fundamental_derivatives(R, t, basis, K1_inv, K2_inv), d_x[None]])


class FocalFit(NamedTuple):
    """What :func:`fit_focal_scale` or :func:`fit_focal_ratio` found.

    Attributes
    ----------
    scale : float
        The factor that best explains the matches: the focal length as a multiple of
        the calibration's (:func:`fit_focal_scale`), or image 2's over image 1's
        (:func:`fit_focal_ratio`); 1 when the calibration fits.
    sigma_log : float
        First-order standard deviation of ``log(scale)`` (inf when the matches do
        not determine it, e.g. without rotation).
    R, t : (3, 3), (3,) float64
        The pose refined with it, ``x_cam2 = R x_cam1 + t`` (``|t| = 1``).
    weights : (float, float)
        :data:`COMMON` or :data:`RATIO`: how ``scale`` applies to each image.
    """

    scale: float
    sigma_log: float
    R: FloatArray
    t: FloatArray
    weights: tuple[float, float] = COMMON

    @property
    def parameter(self) -> float:
        """The fitted unknown, to start a refit from (``scale``)."""
        return self.scale

    def residuals(self, K: ArrayLike, pts1: ArrayLike, pts2: ArrayLike) -> FloatArray:
        """Signed Sampson distances ``(N,)`` in pixels of the correspondences ``pts1, pts2``
        ``(N, 2)`` to the fitted pose and focal lengths (:meth:`fundamental`).

        Parameters
        ----------
        K : (3, 3) array_like
            The calibration the fit started from.
        pts1, pts2 : (N, 2) array_like
            Pixels in images 1 and 2.

        Returns
        -------
        (N,) float64 ndarray
        """
        return sampson_residuals(self.fundamental(K), np.asarray(pts1, dtype=np.float64),
                                 np.asarray(pts2, dtype=np.float64))

    def fundamental(self, K: ArrayLike) -> FloatArray:
        """``(3, 3)`` the fundamental matrix of the fitted pose and focal lengths, for
        the calibration ``K`` the fit started from.

        Parameters
        ----------
        K : (3, 3) array_like
            The calibration the fit started from.

        Returns
        -------
        (3, 3) float64 ndarray
            ``F`` with ``x2^T F x1 = 0``.
        """
        K_inv = np.linalg.inv(np.asarray(K, dtype=np.float64))
        return scaled_fundamental(self.R, self.t, float(np.log(self.scale)), self.weights,
                                  K_inv)


def _fit_focal(R: ArrayLike, t: ArrayLike, pts1: ArrayLike, pts2: ArrayLike, K: ArrayLike,
               weights: tuple[float, float], loss: str, scale_px: float,
               max_iterations: int, initial_scale: float) -> FocalFit:
    """The robust Sampson refinement of the pose with the factor of ``weights``."""
    R = np.asarray(R, dtype=np.float64)
    t = np.asarray(t, dtype=np.float64).reshape(3)
    t = t / np.linalg.norm(t)
    h1 = to_homogeneous(np.asarray(pts1, dtype=np.float64))
    h2 = to_homogeneous(np.asarray(pts2, dtype=np.float64))
    K_inv = np.linalg.inv(np.asarray(K, dtype=np.float64))

    def residuals(R_: FloatArray, t_: FloatArray, x: float) -> tuple[FloatArray, FloatArray]:
        F_ = scaled_fundamental(R_, t_, x, weights, K_inv)
        return sampson_residuals_homogeneous(F_, h1, h2), F_

    def jacobian(R_: FloatArray, t_: FloatArray, x: float, basis: FloatArray,
                 F_: FloatArray) -> FloatArray:
        dF = focal_fundamental_derivatives(R_, t_, x, weights, basis, K_inv)
        return sampson_jacobian(F_, dF, h1, h2)

    # The same first-order covariance as the pose's (refinement.relative_pose_covariance).
    R, t, x, sigma_log = refine_pose_and_parameter(R, t, float(np.log(initial_scale)), residuals,
                                              jacobian, MAX_LOG_SCALE, loss, scale_px,
                                              max_iterations)
    return FocalFit(float(np.exp(x)), sigma_log, R, t, weights)


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
    :func:`scene3D.optim.refinement.refine_relative_pose` does, from ``s = initial_scale``.
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
        :func:`scene3D.optim.refinement.refine_relative_pose`.

    Returns
    -------
    FocalFit
    """
    return _fit_focal(R, t, pts1, pts2, K, COMMON, loss, scale_px, max_iterations,
                      initial_scale)


def fit_focal_ratio(
    R: ArrayLike,
    t: ArrayLike,
    pts1: ArrayLike,
    pts2: ArrayLike,
    K: ArrayLike,
    loss: str = "cauchy",
    scale_px: float = 0.5,
    max_iterations: int = 30,
    initial_ratio: float = 1.0,
) -> FocalFit:
    """Check that one calibration fits both photos: image 2's focal length against image 1's.

    As :func:`fit_focal_scale`, with image 1's focal length divided and image 2's
    multiplied by ``sqrt(r)`` (``r = s2 / s1``, the geometric mean kept at the
    calibration's), from ``r = initial_ratio``. A zoom turned between the shots, or one
    photo cropped and enlarged, shows as ``r`` far from 1: with one ``K`` for both, such
    a pair came back trusted tens of degrees off in translation direction, the zoom
    taken for a move along the optical axis (docs/benchmarks.md#mistakes-a-user-could-make).

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
        :func:`scene3D.optim.refinement.refine_relative_pose`.
    max_iterations : int, default 30
        Most Levenberg-Marquardt iterations.
    initial_ratio : float, default 1.0
        Start of ``r``.


    Returns
    -------
    FocalFit
        ``scale`` is ``r``, ``weights`` :data:`RATIO`.
    """
    return _fit_focal(R, t, pts1, pts2, K, RATIO, loss, scale_px, max_iterations,
                      initial_ratio)
