"""Non-linear refinement of two-view geometry.

- :func:`refine_relative_pose` polishes ``(R, t)`` by minimising the Sampson
  distances (a first-order geometric error in pixels, H&Z section 11.4.3) of the
  inlier correspondences under a robust loss, with a small Levenberg-Marquardt
  solver in numpy (5 unknowns; no scipy import on the default path).
- :func:`bundle_adjust_two_view` refines the pose *and* the 3D points by
  minimising reprojection errors in both images (H&Z section 18.1, the gold
  standard), with scipy ``least_squares``, a sparse Jacobian and a robust loss
  (:mod:`scene3D.bundle`).

In both, ``t`` ends on the unit sphere, since a two-view translation has no scale. Frames as in
:mod:`scene3D.geometry`: ``x_cam2 = R x_cam1 + t``.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike

from .geometry import FloatArray, rotations_from_vectors, skew, to_homogeneous


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


def _tangent_basis(t: FloatArray) -> FloatArray:
    """Two unit vectors ``(2, 3)`` orthogonal to the unit vector ``t`` and to each other."""
    helper = np.eye(3)[int(np.argmin(np.abs(t)))]
    b1 = skew(t) @ helper
    b1 /= np.linalg.norm(b1)
    return np.vstack([b1, skew(t) @ b1])


def _update_pose(
    R: FloatArray, t: FloatArray, dx: FloatArray, basis: FloatArray | None = None
) -> tuple[FloatArray, FloatArray]:
    """Apply a 5-vector step: rotation vector (3) and tangent step of ``t`` (2)."""
    basis = _tangent_basis(t) if basis is None else basis
    R_new = rotations_from_vectors(dx[None, :3])[0] @ R
    t_new = t + dx[3:] @ basis
    return R_new, t_new / np.linalg.norm(t_new)


def _robust_weights(r: FloatArray, loss: str, scale: float) -> FloatArray:
    """IRLS weights ``rho'(r^2)`` of scipy's losses (``r`` in units of ``scale``)."""
    z = (r / scale) ** 2
    if loss == "linear":
        return np.ones_like(z)
    if loss == "cauchy":
        return 1.0 / (1.0 + z)
    if loss == "soft_l1":
        return 1.0 / np.sqrt(1.0 + z)
    if loss == "huber":
        return np.where(z <= 1.0, 1.0, 1.0 / np.sqrt(np.maximum(z, 1e-300)))
    raise ValueError(f"unknown loss {loss!r}; use linear, huber, soft_l1 or cauchy")


def _robust_cost(r: FloatArray, loss: str, scale: float) -> float:
    z = (r / scale) ** 2
    rho = {
        "linear": lambda: z,
        "cauchy": lambda: np.log1p(z),
        "soft_l1": lambda: 2.0 * (np.sqrt(1.0 + z) - 1.0),
        "huber": lambda: np.where(z <= 1.0, z, 2.0 * np.sqrt(z) - 1.0),
    }[loss]()
    return float(scale**2 * np.sum(rho))


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

    def residuals(R_: FloatArray, t_: FloatArray) -> FloatArray:
        return _sampson(K_inv.T @ skew(t_) @ R_ @ K_inv, h1, h2)  # F = K^-T [t]x R K^-1

    r = residuals(R, t)
    cost = _robust_cost(r, loss, scale_px)
    damping = 1e-3
    eps = 1e-7
    for _ in range(max_iterations):
        sqrt_w = np.sqrt(_robust_weights(r, loss, scale_px))
        basis = _tangent_basis(t)
        J = np.empty((len(r), 5))
        for k in range(5):
            step = np.zeros(5)
            step[k] = eps
            J[:, k] = (residuals(*_update_pose(R, t, step, basis)) - r) / eps
        Jw, rw = J * sqrt_w[:, None], r * sqrt_w
        H, g = Jw.T @ Jw, Jw.T @ rw
        improved = False
        while damping < 1e8:
            dx = np.linalg.solve(H + damping * np.diag(np.diag(H) + 1e-12), -g)
            R_new, t_new = _update_pose(R, t, dx, basis)
            r_new = residuals(R_new, t_new)
            cost_new = _robust_cost(r_new, loss, scale_px)
            if cost_new < cost:
                improved = cost - cost_new > 1e-8 * max(cost, 1e-30)
                R, t, r, cost = R_new, t_new, r_new, cost_new
                damping = max(damping / 10.0, 1e-9)
                break
            damping *= 10.0
        if not improved or np.linalg.norm(dx) < 1e-10:
            break
    return R, t


def bundle_adjust_two_view(
    R: ArrayLike,
    t: ArrayLike,
    points3d: ArrayLike,
    pts1: ArrayLike,
    pts2: ArrayLike,
    K: ArrayLike,
    loss: str = "soft_l1",
    scale_px: float = 1.0,
    max_evaluations: int = 100,
) -> tuple[FloatArray, FloatArray, FloatArray]:
    """Two-view bundle adjustment of the pose and the points.

    Minimises the reprojection errors of ``points3d`` in both images with camera
    1 fixed at ``[I | 0]`` (:func:`scene3D.bundle.bundle_adjust`), then rescales
    so that ``|t| = 1`` again.

    Parameters
    ----------
    R, t : (3, 3), (3,) array_like
        Initial pose, ``x_cam2 = R x_cam1 + t``.
    points3d : (N, 3) array_like
        Initial points in the camera-1 frame.
    pts1, pts2 : (N, 2) array_like
        Their observed pixels in image 1 and image 2.
    K : (3, 3) array_like
    loss, scale_px : str, float
        Robust loss and its scale in pixels (scipy's names).

    Returns
    -------
    R, t, points3d : (3, 3), (3,), (N, 3) float64
    """
    from .bundle import Observations, bundle_adjust

    X = np.asarray(points3d, dtype=np.float64)
    n = len(X)
    Rs = np.stack([np.eye(3), np.asarray(R, dtype=np.float64)])
    ts = np.stack([np.zeros(3), np.asarray(t, dtype=np.float64).reshape(3)])
    obs = Observations(np.repeat([0, 1], n), np.tile(np.arange(n), 2),
                       np.vstack([np.asarray(pts1, np.float64), np.asarray(pts2, np.float64)]))
    Rs, ts, X = bundle_adjust(Rs, ts, X, obs, np.asarray(K, np.float64), fixed_view=0,
                              loss=loss, scale_px=scale_px, max_evaluations=max_evaluations)
    scale = np.linalg.norm(ts[1])
    return Rs[1], ts[1] / scale, X / scale
