"""Non-linear refinement of two-view geometry (scipy ``least_squares``).

:func:`refine_relative_pose` polishes ``(R, t)`` by minimising the Sampson
distances (a first-order geometric error in pixels, H&Z section 11.4.3) of the
inlier correspondences. ``t`` stays on the unit sphere: it is updated in the
plane tangent to it and renormalised, since a two-view translation has no scale.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike
from scipy.optimize import least_squares
from scipy.spatial.transform import Rotation

from .geometry import FloatArray, skew, to_homogeneous


def sampson_residuals(F: FloatArray, pts1: FloatArray, pts2: FloatArray) -> FloatArray:
    """Signed Sampson distances ``(N,)`` in pixels of correspondences to ``x2^T F x1 = 0``."""
    h1, h2 = to_homogeneous(pts1), to_homogeneous(pts2)
    Fx1 = h1 @ F.T
    Ftx2 = h2 @ F
    algebraic = np.sum(h2 * Fx1, axis=1)
    norm = np.sqrt(Fx1[:, 0] ** 2 + Fx1[:, 1] ** 2 + Ftx2[:, 0] ** 2 + Ftx2[:, 1] ** 2)
    return algebraic / np.maximum(norm, 1e-300)


def _tangent_basis(t: FloatArray) -> FloatArray:
    """Two unit vectors ``(2, 3)`` orthogonal to ``t`` and to each other."""
    helper = np.eye(3)[int(np.argmin(np.abs(t)))]
    b1 = np.cross(t, helper)
    b1 /= np.linalg.norm(b1)
    return np.vstack([b1, np.cross(t, b1)])


def pose_to_fundamental(R: FloatArray, t: FloatArray, K: FloatArray) -> FloatArray:
    """``F = K^-T [t]x R K^-1`` (not normalised)."""
    K_inv = np.linalg.inv(K)
    return K_inv.T @ skew(t) @ R @ K_inv


def refine_relative_pose(
    R: ArrayLike,
    t: ArrayLike,
    pts1: ArrayLike,
    pts2: ArrayLike,
    K: ArrayLike,
    loss: str = "soft_l1",
    scale_px: float = 1.0,
    max_evaluations: int = 50,
) -> tuple[FloatArray, FloatArray]:
    """Refine a relative pose by minimising Sampson distances.

    Parameters
    ----------
    R, t : (3, 3), (3,) array_like
        Initial pose, ``x_cam2 = R x_cam1 + t``.
    pts1, pts2 : (N, 2) array_like
        Inlier pixels (N >= 5).
    K : (3, 3) array_like
        Intrinsics shared by both views.
    loss, scale_px : str, float
        Robust loss of ``least_squares`` and its inlier scale in pixels.

    Returns
    -------
    R, t : (3, 3), (3,) float64
        Refined pose; ``|t| = 1``.
    """
    R0 = np.asarray(R, dtype=np.float64)
    t0 = np.asarray(t, dtype=np.float64).reshape(3)
    t0 = t0 / np.linalg.norm(t0)
    p1 = np.asarray(pts1, dtype=np.float64)
    p2 = np.asarray(pts2, dtype=np.float64)
    K = np.asarray(K, dtype=np.float64)
    basis = _tangent_basis(t0)

    def unpack(x: FloatArray) -> tuple[FloatArray, FloatArray]:
        R_x = Rotation.from_rotvec(x[:3]).as_matrix() @ R0
        t_x = t0 + x[3:] @ basis
        return R_x, t_x / np.linalg.norm(t_x)

    def residuals(x: FloatArray) -> FloatArray:
        return sampson_residuals(pose_to_fundamental(*unpack(x), K), p1, p2)

    result = least_squares(residuals, np.zeros(5), loss=loss, f_scale=scale_px,
                           max_nfev=max_evaluations, x_scale="jac")
    return unpack(result.x)
