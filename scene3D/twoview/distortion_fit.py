"""The distortion check: the pose refined with one radial lens distortion.

A calibration that leaves out the lens's distortion bends every match by up to a few
percent of its distance from the principal point, and two views can take that bend for
a pose some degrees off with small residuals, well beyond its own sigma
(docs/trust.md#a-lens-distortion-the-calibration-leaves-out). No statistic of the pose
alone shows it. :func:`fit_radial_distortion` refines the pose together with one
coefficient of the division model (Fitzgibbon, 2001; one parameter serves both views,
one lens) about ``K``'s principal point:

    x_u = x_d / (1 + k |x_d|^2)

with ``x_d`` the normalised coordinates ``K^-1 p`` of a matched pixel as given and
``x_u`` those a pinhole camera would have seen (``k < 0``: barrel distortion, ``k``
about the ``k1`` of OpenCV's model for small distortions). Two views determine ``k``
only weakly beside the pose; what the check uses is how far the pose moves when ``k`` is
free (:func:`scene3D.twoview.trust.distortion_warning`).

Frames as in :mod:`scene3D.geometry`: ``x_cam2 = R x_cam1 + t``, ``t`` on the unit
sphere.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np
from numpy.typing import ArrayLike

from ..geometry.conventions import FloatArray, skew, to_homogeneous
from ..geometry.epipolar import fundamental_derivatives
from ..optim.refinement import refine_pose_and_parameter

#: The fit does not step beyond this coefficient either way. The model folds over where
#: ``1 + k |x|^2 = 0``: for ``k = -1`` at the corners of a 90 deg diagonal field of view,
#: within the bound for wider lenses (their photos need a calibration with distortion).
MAX_ABS_K = 1.0


def undistort_division(pts: ArrayLike, K: ArrayLike, k: float) -> FloatArray:
    """Pixels ``(N, 2)`` as a pinhole camera ``K`` would have seen the pixels ``pts``
    ``(N, 2)`` of a lens with the division-model coefficient ``k`` (module docstring).

    Parameters
    ----------
    pts : (N, 2) array_like
        Photographed pixels (OpenCV convention).
    K : (3, 3) array_like
        Intrinsics; the distortion centre is the principal point.
    k : float
        Division-model coefficient.

    Returns
    -------
    (N, 2) float64 ndarray
    """
    h = to_homogeneous(np.asarray(pts, dtype=np.float64).reshape(-1, 2))
    return undistort_homogeneous(h, np.asarray(K, dtype=np.float64), k).u[:, :2]


class Undistorted(NamedTuple):
    """Matched pixels undistorted with ``k``, and how they change with it."""

    u: FloatArray  # (N, 3) homogeneous undistorted pixels
    du: FloatArray  # (N, 3) du / dk (third entries 0)
    g: FloatArray  # (N,) the undistortion's local scale at each pixel, 1 / (1 + k rho^2)
    dg: FloatArray  # (N,) dg / dk


def undistort_homogeneous(h: FloatArray, K: FloatArray, k: float) -> Undistorted:
    """Homogeneous pixels ``(N, 3)`` undistorted with ``k`` (:func:`undistort_division`).

    ``u = c + (p - c) g`` with ``g = 1 / (1 + k rho^2)`` and ``rho^2 = |K^-1 p|^2``, so
    ``du/dk = -(u - c) rho^2 g`` and ``dg/dk = -rho^2 g^2``.

    Parameters
    ----------
    h : (N, 3) float64 ndarray
        Homogeneous photographed pixels (last coordinate 1).
    K : (3, 3) float64 ndarray
        Intrinsics.
    k : float
        Division-model coefficient.

    Returns
    -------
    Undistorted
        ``u`` ``(N, 3)``, ``du/dk`` ``(N, 3)``, ``g`` ``(N,)`` and ``dg/dk`` ``(N,)``.
    """
    c, f = K[:2, 2], np.diag(K)[:2]
    offset = h[:, :2] - c
    rho2 = np.sum((offset / f) ** 2, axis=1)
    g = 1.0 / (1.0 + k * rho2)
    u = np.ones_like(h)
    u[:, :2] = c + offset * g[:, None]
    du = np.zeros_like(h)
    du[:, :2] = -(offset * g[:, None]) * (rho2 * g)[:, None]
    return Undistorted(u, du, g, -rho2 * g**2)


def observed_sampson(F: FloatArray, p1: Undistorted,
                     p2: Undistorted) -> tuple[FloatArray, tuple]:
    """Sampson distances ``(N,)`` of undistorted correspondences to ``x2^T F x1 = 0``,
    in the pixels of the photos as given, and the terms their derivatives reuse.

    The distance divides ``a = x2^T F x1`` by the length of its gradient with respect to
    the matched pixels. Undistorting scales a pixel's neighbourhood by ``g`` (its
    tangential scale; the radial one differs by ``1 - k rho^2``), so with ``l = F x1`` and
    ``m = F^T x2`` that length is ``n = sqrt(g1^2 (m_1^2 + m_2^2) + g2^2 (l_1^2 + l_2^2))``.
    Measured in undistorted pixels instead, a pincushion ``k > 0``, which shrinks the
    image about the principal point, would shrink every distance with it, and the fit
    would prefer it on matches of a lens without distortion (a review: ``k`` ran to the
    bound on noisy matches of distant points).

    Parameters
    ----------
    F : (3, 3) float64 ndarray
        Fundamental matrix, ``x2^T F x1 = 0``.
    p1, p2 : Undistorted
        Undistorted correspondences (:func:`undistort_homogeneous`).

    Returns
    -------
    distances : (N,) float64 ndarray
        Signed Sampson distances (px).
    terms : tuple
        ``(l, m, a, n)`` for :func:`observed_sampson_jacobian`.
    """
    line2 = p1.u @ F.T  # l = F x1, the epipolar line in image 2
    line1 = p2.u @ F  # m = F^T x2, in image 1
    a = np.einsum("ij,ij->i", p2.u, line2)
    n = np.maximum(np.sqrt(p1.g**2 * (line1[:, 0] ** 2 + line1[:, 1] ** 2)
                           + p2.g**2 * (line2[:, 0] ** 2 + line2[:, 1] ** 2)), 1e-300)
    return a / n, (line2, line1, a, n)


def observed_sampson_jacobian(F: FloatArray, dF: FloatArray, p1: Undistorted,
                              p2: Undistorted, terms: tuple) -> FloatArray:
    """Jacobian ``(N, k + 1)`` of :func:`observed_sampson`: for ``F`` moving along ``dF``
    ``(k, 3, 3)``, then for the distortion coefficient.

    ``d(a/n) = da / n - a d(n^2) / (2 n^3)``. Along ``dF``: ``da = x2^T dF x1`` and
    ``d(n^2)/2 = g2^2 l' . dF x1 + g1^2 x2^T dF m'`` (``l', m'``: ``l, m`` with the third
    entry zeroed). Along ``k``: ``da = m . du1 + l . du2`` and ``d(n^2)/2 =
    g1 dg1 |m'|^2 + g1^2 m' . F^T du2 + g2 dg2 |l'|^2 + g2^2 l' . F du1``.

    Parameters
    ----------
    F : (3, 3) float64 ndarray
        Fundamental matrix.
    dF : (k, 3, 3) float64 ndarray
        Derivatives of ``F`` along its ``k`` parameters.
    p1, p2 : Undistorted
        Undistorted correspondences.
    terms : tuple
        As returned by :func:`observed_sampson`.

    Returns
    -------
    (N, k + 1) float64 ndarray
    """
    line2, line1, a, n = terms
    lp, mp = line2.copy(), line1.copy()
    lp[:, 2] = 0.0
    mp[:, 2] = 0.0
    h1, h2 = p1.u, p2.u
    c = (a / n**3)[:, None, None]
    grad = (h2 / n[:, None])[:, :, None] * h1[:, None, :]
    grad -= c * ((p2.g**2)[:, None, None] * lp[:, :, None] * h1[:, None, :]
                 + (p1.g**2)[:, None, None] * h2[:, :, None] * mp[:, None, :])
    J_F = grad.reshape(-1, 9) @ dF.reshape(len(dF), 9).T
    da = np.einsum("ij,ij->i", line1, p1.du) + np.einsum("ij,ij->i", line2, p2.du)
    dl = p1.du @ F.T
    dm = p2.du @ F
    half_dn2 = (p1.g * p1.dg * np.sum(mp**2, axis=1) + p1.g**2 * np.sum(mp * dm, axis=1)
                + p2.g * p2.dg * np.sum(lp**2, axis=1) + p2.g**2 * np.sum(lp * dl, axis=1))
    return np.column_stack([J_F, da / n - a * half_dn2 / n**3])


class DistortionFit(NamedTuple):
    """What :func:`fit_radial_distortion` found.

    Attributes
    ----------
    k : float
        The division-model coefficient that best explains the matches (0: none).
    sigma : float
        First-order standard deviation of ``k`` (inf when the matches do not
        determine it).
    R, t : (3, 3), (3,) float64
        The pose refined with it, ``x_cam2 = R x_cam1 + t`` (``|t| = 1``).
    """

    k: float
    sigma: float
    R: FloatArray
    t: FloatArray

    @property
    def parameter(self) -> float:
        """The fitted unknown, to start a refit from (``k``)."""
        return self.k

    def residuals(self, K: ArrayLike, pts1: ArrayLike, pts2: ArrayLike) -> FloatArray:
        """Signed Sampson distances ``(N,)`` of the correspondences ``pts1, pts2`` ``(N, 2)``,
        undistorted with ``k``, to the fitted pose under ``K``, in the pixels given
        (:func:`observed_sampson`).

        Parameters
        ----------
        K : (3, 3) array_like
            The calibration's intrinsics.
        pts1, pts2 : (N, 2) array_like
            Photographed pixels in images 1 and 2.

        Returns
        -------
        (N,) float64 ndarray
        """
        K = np.asarray(K, dtype=np.float64)
        K_inv = np.linalg.inv(K)
        F = K_inv.T @ skew(self.t) @ self.R @ K_inv
        p1 = undistort_homogeneous(to_homogeneous(np.asarray(pts1, dtype=np.float64)), K, self.k)
        p2 = undistort_homogeneous(to_homogeneous(np.asarray(pts2, dtype=np.float64)), K, self.k)
        return observed_sampson(F, p1, p2)[0]

    def shift_px(self, K: ArrayLike, pixel: ArrayLike) -> float:
        """How far, in pixels, undistorting with ``k`` moves ``pixel`` ``(2,)`` (an image
        corner: the largest shift in the image).

        Parameters
        ----------
        K : (3, 3) array_like
            The calibration's intrinsics.
        pixel : (2,) array_like
            A pixel (OpenCV convention).

        Returns
        -------
        float
        """
        pixel = np.asarray(pixel, dtype=np.float64).reshape(1, 2)
        return float(np.linalg.norm(undistort_division(pixel, K, self.k) - pixel))


def fit_radial_distortion(
    R: ArrayLike,
    t: ArrayLike,
    pts1: ArrayLike,
    pts2: ArrayLike,
    K: ArrayLike,
    loss: str = "cauchy",
    scale_px: float = 0.5,
    max_iterations: int = 30,
    initial_k: float = 0.0,
) -> DistortionFit:
    """The pose refined together with one radial distortion of the lens.

    Minimises the robust Sampson distances of the correspondences, undistorted by the
    division model with coefficient ``k`` (module docstring) about ``K``'s principal
    point and measured in the pixels given (:func:`observed_sampson`), as
    :func:`scene3D.optim.refinement.refine_relative_pose` does for the pose alone,
    from ``R, t`` and ``k = initial_k``.

    Parameters
    ----------
    R, t : (3, 3), (3,) array_like
        Pose found with ``K`` and no distortion, ``x_cam2 = R x_cam1 + t``.
    pts1, pts2 : (N, 2) array_like
        Inlier pixels (N >= 7).
    K : (3, 3) array_like
        The calibration's intrinsics (both views).
    loss, scale_px : str, float
        Robust loss and its scale in pixels, as for
        :func:`scene3D.optim.refinement.refine_relative_pose`.

    Returns
    -------
    DistortionFit
    """
    R = np.asarray(R, dtype=np.float64)
    t = np.asarray(t, dtype=np.float64).reshape(3)
    t = t / np.linalg.norm(t)
    K = np.asarray(K, dtype=np.float64)
    K_inv = np.linalg.inv(K)
    h1 = to_homogeneous(np.asarray(pts1, dtype=np.float64))
    h2 = to_homogeneous(np.asarray(pts2, dtype=np.float64))

    def residuals(R_: FloatArray, t_: FloatArray, k: float) -> tuple[FloatArray, tuple]:
        p1, p2 = undistort_homogeneous(h1, K, k), undistort_homogeneous(h2, K, k)
        F_ = K_inv.T @ skew(t_) @ R_ @ K_inv
        r_, terms = observed_sampson(F_, p1, p2)
        return r_, (F_, p1, p2, terms)

    def jacobian(R_: FloatArray, t_: FloatArray, k: float, basis: FloatArray,
                 cache: tuple) -> FloatArray:
        F_, p1, p2, terms = cache
        dF = fundamental_derivatives(R_, t_, basis, K_inv)
        return observed_sampson_jacobian(F_, dF, p1, p2, terms)

    R, t, k, sigma = refine_pose_and_parameter(R, t, initial_k, residuals, jacobian, MAX_ABS_K,
                                          loss, scale_px, max_iterations)
    return DistortionFit(float(k), sigma, R, t)
