"""First-order uncertainty of points triangulated from two views.

The pose's covariance they carry is that of :mod:`scene3D.optim.uncertainty`, in the
parametrisation of :mod:`scene3D.optim.parametrisation`; frames as in
:mod:`scene3D.geometry` (points in the camera-1 frame, ``x_cam2 = R x_cam1 + t``).
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike

from ..geometry.conventions import FloatArray, project_with_jacobian, skews
from .parametrisation import tangent_basis


def _triangulation_normals(points3d: ArrayLike, K: ArrayLike, R: ArrayLike,
                           t: ArrayLike) -> tuple[FloatArray, FloatArray]:
    """``G = J_X^T J_X`` ``(N, 3, 3)`` and ``M = J_X^T J_p`` ``(N, 3, 5)`` of each point's
    four reprojection residuals (``J_X`` by the point, ``J_p`` by the pose step)."""
    X = np.asarray(points3d, dtype=np.float64).reshape(-1, 3)
    K = np.asarray(K, dtype=np.float64)
    R = np.asarray(R, dtype=np.float64)
    t = np.asarray(t, dtype=np.float64).reshape(3)
    n = len(X)
    rotated = X @ R.T
    _, J1 = project_with_jacobian(X, K)
    _, J2 = project_with_jacobian(rotated + t, K)
    J2R = J2 @ R  # image 2's rows by X
    # R <- exp([w]x) R moves R X by -[R X]x w; t moves along the tangent basis.
    dY = np.concatenate([-skews(rotated), np.broadcast_to(tangent_basis(t).T, (n, 3, 2))],
                        axis=2)  # (N, 3, 5)
    G = np.swapaxes(J1, 1, 2) @ J1 + np.swapaxes(J2R, 1, 2) @ J2R
    M = np.swapaxes(J2R, 1, 2) @ (J2 @ dY)  # image 1's rows do not depend on the pose
    return G, M


def point_covariances(points3d: ArrayLike, K: ArrayLike, R: ArrayLike, t: ArrayLike,
                      pose_covariance: ArrayLike, noise_px: float) -> FloatArray:
    """First-order covariances ``(N, 3, 3)`` of triangulated points (camera-1 frame).

    A point ``X`` triangulated by minimising its reprojection errors in both images
    moves, to first order, with the pixel noise of its two observations (``noise_px``
    per coordinate, independent) and with the pose (``pose_covariance`` ``(5, 5)``,
    parametrisation of :mod:`scene3D.optim.parametrisation`, basis
    :func:`tangent_basis` ``(t)``).
    With ``J_X`` ``(4, 3)`` the derivative of its four reprojection residuals by
    ``X`` and ``J_p`` ``(4, 5)`` by the pose, ``A = (J_X^T J_X)^-1 J_X^T`` and
    ``cov X = A (noise_px^2 I + J_p C J_p^T) A^T`` (H&Z section 5.2.3 for the
    propagation; the pose and each point taken as independent, which holds to
    first order when the pose rests on many points).

    Parameters
    ----------
    points3d : (N, 3) array_like
        Points in the camera-1 frame, in units of the baseline (``|t| = 1``).
    K : (3, 3) array_like
    R, t : (3, 3), (3,) array_like
        ``x_cam2 = R x_cam1 + t``.
    pose_covariance : (5, 5) array_like
    noise_px : float

    Returns
    -------
    (N, 3, 3) float64
        In units of the baseline squared; infinite when the pose covariance is.
    """
    C = np.asarray(pose_covariance, dtype=np.float64)
    G, M = _triangulation_normals(points3d, K, R, t)
    if not np.all(np.isfinite(C)):
        return np.full((len(G), 3, 3), np.inf)
    # With G = J_X^T J_X: A A^T = G^-1, so cov X = noise^2 G^-1 + B C B^T with
    # B = A J_p = G^-1 M.
    G_inv = np.linalg.inv(G)
    B = G_inv @ M  # (N, 3, 5)
    return noise_px**2 * G_inv + B @ C @ np.swapaxes(B, 1, 2)


def depth_sigmas(points3d: ArrayLike, K: ArrayLike, R: ArrayLike, t: ArrayLike,
                 pose_covariance: ArrayLike, noise_px: float) -> FloatArray:
    """1-sigma depth ``(N,)`` of each point in camera 1, in units of the baseline.

    The ``z`` entry of :func:`point_covariances` (computed from the third row of
    ``G^-1`` alone, by cofactors); divide by the depth (``points3d[:, 2]``) for a
    relative uncertainty. Infinite for a point whose two rays are parallel (on the
    line through both camera centres): nothing fixes its depth.

    Parameters
    ----------
    points3d : (N, 3) array_like
        Points in the camera-1 frame, the baseline ``|t| = 1``.
    K : (3, 3) array_like
        Intrinsics shared by both views.
    R, t : (3, 3), (3,) array_like
        Relative pose, ``x_cam2 = R x_cam1 + t``.
    pose_covariance : (5, 5) array_like
        Covariance of the pose.
    noise_px : float
        Keypoint noise per coordinate (px).

    Returns
    -------
    (N,) float64 ndarray
    """
    C = np.asarray(pose_covariance, dtype=np.float64)
    G, M = _triangulation_normals(points3d, K, R, t)
    if not np.all(np.isfinite(C)):
        return np.full(len(G), np.inf)
    g = G.reshape(-1, 9)
    # Third row of the inverse of a symmetric 3x3 matrix: cofactors over the determinant.
    row = np.column_stack([g[:, 1] * g[:, 5] - g[:, 2] * g[:, 4],
                           g[:, 2] * g[:, 1] - g[:, 0] * g[:, 5],
                           g[:, 0] * g[:, 4] - g[:, 1] ** 2])
    det = (g[:, 0] * (g[:, 4] * g[:, 8] - g[:, 5] ** 2)
           + g[:, 1] * (g[:, 5] * g[:, 2] - g[:, 1] * g[:, 8]) + g[:, 2] * row[:, 0])
    known = det > 0  # rays that meet at an angle; parallel ones leave the depth unknown
    row[known] /= det[known, None]
    b = np.einsum("ni,nij->nj", row, M)  # (N, 5): the depth's derivative by the pose
    variance = noise_px**2 * row[:, 2] + np.einsum("ni,ij,nj->n", b, C, b)
    return np.where(known, np.sqrt(np.maximum(variance, 0.0)), np.inf)
