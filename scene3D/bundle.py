"""Multi-view bundle adjustment (H&Z section 18.1) with scipy ``least_squares``.

Cameras are world-to-camera poses ``x_cam = R X + t`` sharing one ``K``. The
unknowns are a rotation-vector update and a translation per free camera and the
3D points; the reference camera stays fixed (it fixes the frame; the overall
scale is left to the damping of the trust region). Every residual (one
observation, 2 rows) depends on one camera and one point, so the Jacobian is
sparse and scipy computes it with few function evaluations.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .geometry import FloatArray, rotations_from_vectors


@dataclass(frozen=True)
class Observations:
    """Which point is seen where: ``point[k]`` is seen by ``view[k]`` at pixel ``xy[k]``.

    Attributes
    ----------
    view : (O,) int
    point : (O,) int
    xy : (O, 2) float64
        Pixel coordinates (OpenCV convention).
    """

    view: np.ndarray
    point: np.ndarray
    xy: FloatArray


def reprojection_residuals(
    R: FloatArray, t: FloatArray, points3d: FloatArray, obs: Observations, K: FloatArray
) -> FloatArray:
    """Reprojection errors ``(O, 2)`` in pixels (projection minus observation)."""
    cam = np.einsum("oij,oj->oi", R[obs.view], points3d[obs.point]) + t[obs.view]
    pix = cam @ K.T
    return pix[:, :2] / pix[:, 2:3] - obs.xy


def bundle_adjust(
    R: FloatArray,
    t: FloatArray,
    points3d: FloatArray,
    obs: Observations,
    K: FloatArray,
    fixed_view: int,
    loss: str = "soft_l1",
    scale_px: float = 1.0,
    max_evaluations: int = 50,
) -> tuple[FloatArray, FloatArray, FloatArray]:
    """Refine all cameras but ``fixed_view`` and all points.

    Parameters
    ----------
    R, t : (V, 3, 3), (V, 3)
        World-to-camera poses (views never observed are left as they are).
    points3d : (P, 3)
        World points.
    obs : Observations
        The measurements.
    K : (3, 3)
        Intrinsics shared by every view.
    loss, scale_px : str, float
        scipy robust loss and its scale in pixels.

    Returns
    -------
    R, t, points3d
        Refined copies.
    """
    from scipy.optimize import least_squares
    from scipy.sparse import csr_matrix

    num_views, num_points = len(R), len(points3d)
    free = np.array([v for v in np.unique(obs.view) if v != fixed_view], dtype=int)
    slot = np.full(num_views, -1, dtype=int)
    slot[free] = np.arange(len(free))
    n_cam = 6 * len(free)

    def unpack(x: FloatArray) -> tuple[FloatArray, FloatArray, FloatArray]:
        R_x, t_x = R.copy(), t.copy()
        if len(free):
            params = x[:n_cam].reshape(-1, 6)
            R_x[free] = rotations_from_vectors(params[:, :3]) @ R[free]
            t_x[free] = t[free] + params[:, 3:]
        return R_x, t_x, x[n_cam:].reshape(num_points, 3)

    def residuals(x: FloatArray) -> FloatArray:
        R_x, t_x, X = unpack(x)
        return reprojection_residuals(R_x, t_x, X, obs, K).ravel()

    # Sparsity: rows 2k, 2k+1 depend on the observing camera (6) and the point (3).
    num_obs = len(obs.view)
    rows, cols = [], []
    obs_rows = np.repeat(np.arange(num_obs) * 2, 2) + np.tile([0, 1], num_obs)
    cam_slot = np.repeat(slot[obs.view], 2)
    has_cam = cam_slot >= 0
    for k in range(6):
        rows.append(obs_rows[has_cam])
        cols.append(6 * cam_slot[has_cam] + k)
    point_col = n_cam + 3 * np.repeat(obs.point, 2)
    for k in range(3):
        rows.append(obs_rows)
        cols.append(point_col + k)
    rows_all, cols_all = np.concatenate(rows), np.concatenate(cols)
    sparsity = csr_matrix((np.ones(len(rows_all), dtype=np.int8), (rows_all, cols_all)),
                          shape=(2 * num_obs, n_cam + 3 * num_points))
    x0 = np.concatenate([np.zeros(n_cam), points3d.ravel()])
    result = least_squares(residuals, x0, jac_sparsity=sparsity, loss=loss, f_scale=scale_px,
                           max_nfev=max_evaluations, x_scale="jac", method="trf",
                           tr_solver="lsmr")
    return unpack(result.x)
