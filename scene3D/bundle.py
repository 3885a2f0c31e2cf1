"""Multi-view bundle adjustment (H&Z section 18.1).

Cameras are world-to-camera poses ``x_cam = R X + t`` sharing one ``K``. The
unknowns are a rotation-vector update (``R <- exp([w]x) R``) and a translation
step per free camera, and the 3D points; the reference camera stays fixed (it
fixes the frame; the overall scale is held by the damping). Every observation
depends on one camera and one point, so Levenberg-Marquardt solves its normal
equations with the points eliminated (:mod:`scene3D.schur`): one system of six
unknowns per camera, then a 3x3 solve per point.

Extending it: a parameter shared by every view (a focal length refined with the
poses) would add one column to every observation's Jacobian, and one row and
column to the reduced camera system outside the per-point blocks.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass

import numpy as np

from .geometry import FloatArray, project_with_jacobian, rotations_from_vectors, skews
from .refinement import _levenberg_marquardt, _reweighting, _robust_cost
from .schur import normal_equations, solve_damped


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
    num_points = len(points3d)
    free = np.setdiff1d(np.unique(obs.view), np.atleast_1d(np.asarray(fixed_view, dtype=int)))
    slot = np.full(len(R), -1, dtype=int)
    slot[free] = np.arange(len(free))
    camera = slot[obs.view]

    def evaluate(R_: FloatArray, t_: FloatArray, X_: FloatArray) -> tuple[tuple, float]:
        r_ = reprojection_residuals(R_, t_, X_, obs, K)
        return (R_, t_, X_, r_), _robust_cost(r_, loss, scale_px)

    def linearize(state: tuple) -> Callable[[float], tuple]:
        R_, t_, X_, r_ = state
        R_obs = R_[obs.view]
        rotated = np.einsum("oij,oj->oi", R_obs, X_[obs.point])
        _, J = project_with_jacobian(rotated + t_[obs.view], K)
        # d(R X + t) / d(w, dt) = [-[R X]x | I]; d(R X + t) / dX = R.
        J_camera = np.concatenate([J @ -skews(rotated), J], axis=2)  # (O, 2, 6)
        J_point = J @ R_obs
        row_scale, rw = _reweighting(r_, loss, scale_px)
        ne = normal_equations(J_camera * row_scale[:, :, None], camera,
                              J_point * row_scale[:, :, None], obs.point, rw, len(free),
                              num_points)

        def try_step(damping: float) -> tuple[tuple, float]:
            step_camera, step_point = solve_damped(ne, damping)
            R_new, t_new = R_.copy(), t_.copy()
            R_new[free] = rotations_from_vectors(step_camera[:, :3]) @ R_[free]
            t_new[free] = t_[free] + step_camera[:, 3:]
            return evaluate(R_new, t_new, X_ + step_point)

        return try_step

    state, cost = evaluate(np.array(R, np.float64), np.array(t, np.float64),
                           np.asarray(points3d, np.float64))
    R, t, X, _ = _levenberg_marquardt(state, cost, linearize, max_iterations, tolerance)
    return R, t, X
