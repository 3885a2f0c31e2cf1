"""Fundamental and essential matrices: robust estimation and the relations between them.

The robust ``F`` (USAC, then the normalised 8-point algorithm) and ``H``, the distances
of correspondences to a model (the Sampson distances, their Jacobian and ``F``'s derivatives
by a pose step, which the refinements of :mod:`scene3D.optim` and :mod:`scene3D.twoview`
share), ``E`` from a pose and ``F`` from ``E``, epipolar residuals and lines. The robust fit
of ``E`` (restarts, local optimisation and the noise-adaptive thresholds) is in
:mod:`scene3D.twoview.essential_fit`.

Conventions: ``x2^T F x1 = 0`` with pixel coordinates, ``E = [t]x R`` with
``x_cam2 = R x_cam1 + t`` (Hartley & Zisserman, sections 9.2 and 9.6).
"""

from __future__ import annotations

import cv2
import numpy as np
from numpy.typing import ArrayLike

from .conventions import (
    FloatArray,
    as_matrix,
    as_points2d,
    check_same_length,
    skew,
    to_homogeneous,
)

#: Robust estimator used for F, E and H (OpenCV's USAC family, MAGSAC++ scoring), and for
#: the single start of :func:`scene3D.twoview.essential_fit.fit_essential`.
ROBUST_METHOD = cv2.USAC_MAGSAC


def check_correspondences(pts1: ArrayLike, pts2: ArrayLike,
                          minimum: int) -> tuple[FloatArray, FloatArray]:
    """Validate two arrays of corresponding pixels and their count.

    Parameters
    ----------
    pts1, pts2 : (N, 2) array_like
        Corresponding pixels in images 1 and 2.
    minimum : int
        The fewest correspondences the caller needs.

    Returns
    -------
    p1, p2 : (N, 2) float64

    Raises
    ------
    ValueError
        When either is not ``(N, 2)`` and finite, their lengths differ, or ``N < minimum``.
    """
    p1 = as_points2d(pts1, "pts1")
    p2 = as_points2d(pts2, "pts2")
    check_same_length(p1, p2)
    if len(p1) < minimum:
        raise ValueError(f"need at least {minimum} correspondences, got {len(p1)}")
    return p1, p2


def inlier_mask(mask: np.ndarray | None, n: int) -> np.ndarray:
    """The ``(n,)`` bool inliers of an OpenCV estimator's ``mask`` (any shape; ``None``: none).

    Parameters
    ----------
    mask : (n, 1) or (n,) array or None
        What ``cv2.findFundamentalMat`` and its kin return beside the model.
    n : int
        The number of correspondences given to the estimator.

    Returns
    -------
    (n,) bool
    """
    return np.zeros(n, dtype=bool) if mask is None else mask.ravel().astype(bool)


def sampson_residuals(F: FloatArray, pts1: FloatArray, pts2: FloatArray) -> FloatArray:
    """Signed Sampson distances ``(N,)`` in pixels of correspondences to ``x2^T F x1 = 0``.

    Parameters
    ----------
    F : (3, 3) array
        Fundamental matrix in pixels.
    pts1, pts2 : (N, 2) array
        Corresponding pixels in images 1 and 2.

    Returns
    -------
    (N,) float64
        The first-order geometric error of each correspondence (H&Z section 11.4.3).
    """
    return sampson_residuals_homogeneous(F, to_homogeneous(pts1), to_homogeneous(pts2))


def sampson_residuals_homogeneous(F: FloatArray, h1: FloatArray, h2: FloatArray) -> FloatArray:
    """:func:`sampson_residuals` of homogeneous pixels (for repeated calls on the same points).

    Parameters
    ----------
    F : (3, 3) array
    h1, h2 : (N, 3) array
        Homogeneous pixels ``[x, y, 1]`` in images 1 and 2.

    Returns
    -------
    (N,) float64
    """
    Fx1 = h1 @ F.T
    Ftx2 = h2 @ F
    algebraic = np.einsum("ij,ij->i", h2, Fx1)
    norm = np.sqrt(Fx1[:, 0] ** 2 + Fx1[:, 1] ** 2 + Ftx2[:, 0] ** 2 + Ftx2[:, 1] ** 2)
    return algebraic / np.maximum(norm, 1e-300)


def fundamental_derivatives(R: FloatArray, t: FloatArray, basis: FloatArray,
                            K_inv: FloatArray, K2_inv: FloatArray | None = None) -> FloatArray:
    """Derivatives of ``F = K2^-T [t]x R K^-1`` by a pose step ``x`` ``(5,)``.

    The step is :func:`scene3D.optim.uncertainty.update_pose`'s: ``R <- exp([w]x) R`` gives
    ``dE/dw_k = [t]x [e_k]x R``; ``t <- t + d @ basis`` (then renormalised, which is
    second order since ``basis`` is orthogonal to ``t``) gives ``dE/dd_k = [b_k]x R``.

    Parameters
    ----------
    R : (3, 3) array
        ``R_cam2_from_cam1``.
    t : (3,) array
        Unit translation, ``x_cam2 = R x_cam1 + t``.
    basis : (2, 3) array
        Orthonormal rows spanning the tangent plane of ``t``
        (:func:`scene3D.optim.uncertainty.tangent_basis`).
    K_inv : (3, 3) array
        Inverse intrinsics of image 1.
    K2_inv : (3, 3) array, optional
        Inverse intrinsics of image 2; ``K_inv`` by default.

    Returns
    -------
    dF : (5, 3, 3) float64
        ``dF / dx_k`` for the rotation vector (3) and then the tangent step of ``t`` (2).
    """
    K2_inv = K_inv if K2_inv is None else K2_inv
    dE = [skew(t) @ skew(axis) @ R for axis in np.eye(3)] + [skew(b) @ R for b in basis]
    return np.stack([K2_inv.T @ d @ K_inv for d in dE])


def sampson_jacobian(F: FloatArray, dF: FloatArray, h1: FloatArray,
                     h2: FloatArray) -> FloatArray:
    """Jacobian of :func:`sampson_residuals_homogeneous` for ``F`` moving along ``dF``.

    With ``a = x2^T F x1``, ``l = F x1``, ``m = F^T x2`` and
    ``n^2 = l_1^2 + l_2^2 + m_1^2 + m_2^2``, the distance ``a / n`` changes by
    ``(x2^T dF x1) / n - a (l' . dF x1 + x2^T dF m') / n^3`` (``l', m'``: ``l, m``
    with the third entry zeroed).

    Parameters
    ----------
    F : (3, 3) array
    dF : (k, 3, 3) array
        Derivatives of ``F`` by ``k`` unknowns (e.g. :func:`fundamental_derivatives`).
    h1, h2 : (N, 3) array
        Homogeneous pixels in images 1 and 2.

    Returns
    -------
    J : (N, k) float64
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


def estimate_fundamental(
    pts1: ArrayLike,
    pts2: ArrayLike,
    threshold_px: float = 1.0,
    confidence: float = 0.999,
    max_iters: int = 10000,
) -> tuple[FloatArray, np.ndarray]:
    """Robustly estimate the fundamental matrix (USAC MAGSAC++).

    Parameters
    ----------
    pts1, pts2 : (N, 2) array_like
        Corresponding pixels, N >= 8.
    threshold_px : float
        Inlier threshold on the distance to the epipolar line, in pixels. The
        book's 0.1 px rejects most correct matches; 1 px suits sub-pixel
        keypoints at the book's working size.

    Returns
    -------
    F : (3, 3) float64
        Rank-2 fundamental matrix with unit Frobenius norm, ``x2^T F x1 = 0``.
    inliers : (N,) bool
    """
    p1, p2 = check_correspondences(pts1, pts2, 8)
    F, mask = cv2.findFundamentalMat(p1, p2, ROBUST_METHOD, threshold_px, confidence, max_iters)
    if F is None or F.shape != (3, 3):
        return np.full((3, 3), np.nan), np.zeros(len(p1), dtype=bool)
    inliers = inlier_mask(mask, len(p1))
    if inliers.sum() >= 8:
        # Polish: normalised 8-point least squares over all inliers (exact without noise).
        F = fundamental_8point(p1[inliers], p2[inliers])
    return F / np.linalg.norm(F), inliers


def _hartley_normalization(points: FloatArray) -> FloatArray:
    """Similarity ``T`` (3, 3) moving points to zero mean and mean distance sqrt(2)."""
    centroid = points.mean(axis=0)
    scale = np.sqrt(2.0) / max(np.linalg.norm(points - centroid, axis=1).mean(), 1e-12)
    return np.array([[scale, 0, -scale * centroid[0]], [0, scale, -scale * centroid[1]],
                     [0, 0, 1.0]])


def fundamental_8point(pts1: ArrayLike, pts2: ArrayLike) -> FloatArray:
    """Normalised 8-point algorithm (H&Z algorithm 11.1), rank 2 enforced, unit norm.

    A least-squares fit over all the given correspondences (N >= 8): use it on
    inliers only.

    Parameters
    ----------
    pts1, pts2 : (N, 2) array_like
        Corresponding pixels in images 1 and 2, N >= 8.

    Returns
    -------
    (3, 3) float64 ndarray
        ``F`` with ``x2^T F x1 = 0``, rank 2 and unit Frobenius norm.
    """
    p1, p2 = check_correspondences(pts1, pts2, 8)
    T1, T2 = _hartley_normalization(p1), _hartley_normalization(p2)
    x1 = to_homogeneous(p1) @ T1.T
    x2 = to_homogeneous(p2) @ T2.T
    A = np.einsum("ni,nj->nij", x2, x1).reshape(-1, 9)  # rows: kron(x2, x1)
    F = np.linalg.svd(A)[2][-1].reshape(3, 3)
    U, S, Vt = np.linalg.svd(F)
    F = U @ np.diag([S[0], S[1], 0.0]) @ Vt
    F = T2.T @ F @ T1
    return F / np.linalg.norm(F)


def essential_distances(E: ArrayLike, pts1: ArrayLike, pts2: ArrayLike,
                        K: ArrayLike) -> FloatArray:
    """Sampson distances ``(N,)`` in pixels of correspondences to the epipolar geometry of ``E``.

    A correspondence is an inlier of ``E`` when its distance is at most the threshold.

    Parameters
    ----------
    E : (3, 3) array_like
        Essential matrix, ``x2n^T E x1n = 0``.
    pts1, pts2 : (N, 2) array_like
        Corresponding pixels in images 1 and 2.
    K : (3, 3) array_like
        Intrinsics shared by both views.

    Returns
    -------
    (N,) float64 ndarray
    """
    return np.abs(sampson_residuals(fundamental_from_essential(E, K), pts1, pts2))


def estimate_homography(
    pts1: ArrayLike, pts2: ArrayLike, threshold_px: float = 1.0, confidence: float = 0.999
) -> tuple[FloatArray, np.ndarray]:
    """Robustly estimate a homography ``x2 ~ H x1``; used to detect planar scenes and rotations.

    After USAC MAGSAC++ the homography is refitted by least squares on its
    inliers, and the inliers are those with a transfer error in image 2 below
    ``2 * threshold_px`` (noise in both images adds up in the transfer).

    Returns ``(H, inliers)``; ``H`` is NaN when no homography was found.

    Parameters
    ----------
    pts1, pts2 : (N, 2) array_like
        Corresponding pixels in images 1 and 2, N >= 4.
    threshold_px : float, default 1.0
        RANSAC threshold (px).
    confidence : float, default 0.999
        RANSAC confidence.

    Returns
    -------
    H : (3, 3) float64 ndarray
    inliers : (N,) bool ndarray
    """
    p1, p2 = check_correspondences(pts1, pts2, 4)
    H, mask = cv2.findHomography(p1, p2, ROBUST_METHOD, threshold_px, maxIters=10000,
                                 confidence=confidence)
    if H is None:
        return np.full((3, 3), np.nan), np.zeros(len(p1), dtype=bool)
    inliers = inlier_mask(mask, len(p1))
    if inliers.sum() >= 4:
        H_ls, _ = cv2.findHomography(p1[inliers], p2[inliers], 0)
        if H_ls is not None:
            H = H_ls
    return H, homography_transfer_errors(H, p1, p2) < 2.0 * threshold_px


def homography_transfer_errors(H: ArrayLike, pts1: ArrayLike, pts2: ArrayLike) -> FloatArray:
    """Distances ``(N,)`` in pixels between ``x2`` and ``H x1``.

    Parameters
    ----------
    H : (3, 3) array_like
        Homography ``x2 ~ H x1``.
    pts1, pts2 : (N, 2) array_like
        Corresponding pixels in images 1 and 2.

    Returns
    -------
    (N,) float64 ndarray
        inf where ``H x1`` is at infinity.
    """
    mapped = to_homogeneous(np.asarray(pts1, dtype=np.float64)) @ np.asarray(H).T
    with np.errstate(divide="ignore", invalid="ignore"):
        mapped = mapped[:, :2] / mapped[:, 2:3]
    errors = np.linalg.norm(mapped - np.asarray(pts2, dtype=np.float64), axis=1)
    return np.where(np.isfinite(errors), errors, np.inf)


def essential_from_pose(R: ArrayLike, t: ArrayLike) -> FloatArray:
    """``E = [t]x R`` for ``x_cam2 = R x_cam1 + t`` (H&Z eq. 9.12).

    Parameters
    ----------
    R : (3, 3) array_like
        ``R_cam2_from_cam1``.
    t : (3,) array_like
        Translation in the camera-2 frame (camera 1's centre seen from camera 2); its
        norm scales ``E``.

    Returns
    -------
    E : (3, 3) float64
        Essential matrix with ``x2n^T E x1n = 0`` for normalised image coordinates
        ``xn = K^-1 [u, v, 1]``; not normalised.
    """
    return skew(t) @ np.asarray(R, dtype=np.float64)


def fundamental_from_essential(
    E: ArrayLike, K1: ArrayLike, K2: ArrayLike | None = None
) -> FloatArray:
    """``F = K2^-T E K1^-1`` scaled to unit Frobenius norm (H&Z eq. 9.12).

    Parameters
    ----------
    E : (3, 3) array_like
        Essential matrix, ``x2n^T E x1n = 0`` in normalised coordinates.
    K1, K2 : (3, 3) array_like
        Intrinsics of images 1 and 2 (pixels); ``K2`` defaults to ``K1``.

    Returns
    -------
    F : (3, 3) float64
        Fundamental matrix in pixels, ``x2^T F x1 = 0`` (OpenCV pixel convention), unit
        Frobenius norm.
    """
    K1 = np.asarray(K1, dtype=np.float64)
    K2 = K1 if K2 is None else np.asarray(K2, dtype=np.float64)
    F = np.linalg.inv(K2).T @ np.asarray(E, dtype=np.float64) @ np.linalg.inv(K1)
    return F / np.linalg.norm(F)


def epipolar_residuals(F: ArrayLike, pts1: ArrayLike, pts2: ArrayLike) -> FloatArray:
    """Symmetric point-to-epipolar-line distances in pixels, ``(N,)``.

    The mean of the distance of ``x2`` to ``F x1`` and of ``x1`` to ``F^T x2``.

    Parameters
    ----------
    F : (3, 3) array_like
        Fundamental matrix, ``x2^T F x1 = 0``.
    pts1, pts2 : (N, 2) array_like
        Corresponding pixels in images 1 and 2.

    Returns
    -------
    (N,) float64 ndarray
    """
    p1, p2 = check_correspondences(pts1, pts2, 1)
    F = np.asarray(F, dtype=np.float64)
    h1, h2 = to_homogeneous(p1), to_homogeneous(p2)
    lines2 = h1 @ F.T  # l2 = F x1
    lines1 = h2 @ F  # l1 = F^T x2
    algebraic = np.abs(np.sum(h2 * lines2, axis=1))
    d2 = algebraic / np.hypot(lines2[:, 0], lines2[:, 1])
    d1 = algebraic / np.hypot(lines1[:, 0], lines1[:, 1])
    return 0.5 * (d1 + d2)


def epipolar_lines(F: ArrayLike, points: ArrayLike, which_image: int) -> FloatArray:
    """Epipolar lines ``(N, 3)`` (``a x + b y + c = 0``, ``a^2 + b^2 = 1``).

    ``which_image=1``: ``points`` are in image 1 and the lines ``F x1`` in image 2;
    ``which_image=2``: ``points`` are in image 2 and the lines ``F^T x2`` in image 1.

    Raises ``ValueError`` for an ``F`` that is not a finite 3x3 matrix, or is zero.

    Parameters
    ----------
    F : (3, 3) array_like
        Fundamental matrix, ``x2^T F x1 = 0``.
    points : (N, 2) array_like
        Pixels in the image ``which_image``.
    which_image : {1, 2}
        The image ``points`` are in.

    Returns
    -------
    (N, 3) float64 ndarray
    """
    if which_image not in (1, 2):
        raise ValueError(f"`which_image` must be 1 or 2, got {which_image}")
    F = as_matrix(F, (3, 3), "F")
    if not F.any():
        raise ValueError("`F` is zero: it defines no epipolar lines")
    h = to_homogeneous(as_points2d(points))
    lines = h @ F.T if which_image == 1 else h @ F
    return lines / np.hypot(lines[:, 0], lines[:, 1])[:, None]
