"""Triangulation of many tracks at once, and the checks a new point must pass.

Conventions: world-to-camera poses ``x_cam = R X + t``; pixels of the working images.
Each observation row belongs to one group (a track); every function works on all
groups in one pass of array operations.
"""

from __future__ import annotations

import numpy as np

from ..geometry.conventions import FloatArray, project_with_jacobian
from ..optim.schur import pairs_within_groups


def _sum_rows(group: np.ndarray, values: FloatArray, num_groups: int) -> FloatArray:
    flat = values.reshape(len(values), -1)
    out = np.stack([np.bincount(group, flat[:, k], minlength=num_groups)
                    for k in range(flat.shape[1])], axis=1)
    return out.reshape((num_groups,) + values.shape[1:])


def triangulate_groups(group: np.ndarray, xy: FloatArray, R: FloatArray, t: FloatArray,
                       K: FloatArray, num_groups: int) -> FloatArray:
    """Linear triangulation (DLT, H&Z section 12.2) of every group of observations.

    Parameters
    ----------
    group : (M,) int
        Group (track) of each observation, ``0 <= group < num_groups``.
    xy : (M, 2)
        Pixels.
    R, t : (M, 3, 3), (M, 3)
        World-to-camera pose of each observation's camera.
    K : (3, 3)

    Returns
    -------
    (G, 3) float64
        World points (NaN for a group with fewer than two observations or at infinity).
        The DLT rows use normalised image coordinates (``K^-1 x``), which keeps the
        4x4 systems well conditioned.
    """
    rays = np.column_stack([xy, np.ones(len(xy))]) @ np.linalg.inv(K).T
    P = np.concatenate([R, t[:, :, None]], axis=2)  # (M, 3, 4)
    rows = np.concatenate([rays[:, 0:1] * P[:, 2] - P[:, 0], rays[:, 1:2] * P[:, 2] - P[:, 1]])
    rows /= np.linalg.norm(rows, axis=1, keepdims=True)
    both = np.concatenate([group, group])
    A = _sum_rows(both, rows[:, :, None] * rows[:, None, :], num_groups)  # (G, 4, 4)
    counts = np.bincount(group, minlength=num_groups)
    X = np.full((num_groups, 3), np.nan)
    ok = counts >= 2
    if ok.any():
        h = np.linalg.eigh(A[ok])[1][:, :, 0]  # eigenvector of the smallest eigenvalue
        with np.errstate(divide="ignore", invalid="ignore"):
            pts = h[:, :3] / h[:, 3:4]
        pts[np.abs(h[:, 3]) < 1e-12] = np.nan
        X[ok] = pts
    return X


def observation_errors(X: FloatArray, R: FloatArray, t: FloatArray, xy: FloatArray,
                       K: FloatArray) -> tuple[FloatArray, FloatArray]:
    """Reprojection error (px) and depth of each observation of its point ``X`` ``(M, 3)``.

    Returns ``errors (M,)`` and ``depths (M,)``; NaN points give NaN errors.

    Parameters
    ----------
    X : (M, 3) array_like
        World point of each observation.
    R : (M, 3, 3) array_like
        World-to-camera rotation of each observation's view (``x_cam = R X + t``).
    t : (M, 3) array_like
        Its translation.
    xy : (M, 2) array_like
        The observed pixels (OpenCV convention).
    K : (3, 3) array_like
        Intrinsics.
    """
    cam = np.einsum("mij,mj->mi", R, X) + t
    proj = cam @ K.T
    with np.errstate(divide="ignore", invalid="ignore"):
        err = np.linalg.norm(proj[:, :2] / proj[:, 2:3] - xy, axis=1)
    return err, cam[:, 2]


def max_parallax_deg(group: np.ndarray, X: FloatArray, centers: FloatArray,
                     num_groups: int) -> FloatArray:
    """Largest angle (deg) between two rays of each group ``(G,)`` (0 for fewer than two).

    ``X`` ``(M, 3)``: the point of each observation; ``centers`` ``(M, 3)``: its camera.

    Parameters
    ----------
    group : (M,) int ndarray
        The group (point) of each observation, in ``[0, num_groups)``.
    X : (M, 3) array_like
        World point of each observation.
    centers : (M, 3) array_like
        World position of each observation's camera centre.
    num_groups : int
        Number of groups ``G``.

    Returns
    -------
    (G,) float64 ndarray
        Angles in degrees.
    """
    order = np.argsort(group, kind="stable")
    g = group[order]
    rays = X[order] - centers[order]
    rays /= np.linalg.norm(rays, axis=1, keepdims=True)
    starts = np.flatnonzero(np.r_[True, g[1:] != g[:-1], True]) if len(g) else np.zeros(1, int)
    a, b = pairs_within_groups(starts)
    cos = np.full(num_groups, 1.0)
    if len(a):
        np.minimum.at(cos, g[a], np.einsum("ij,ij->i", rays[a], rays[b]))
    return np.degrees(np.arccos(np.clip(cos, -1.0, 1.0)))


def refine_points(point: np.ndarray, xy: FloatArray, R: FloatArray, t: FloatArray,
                  K: FloatArray, X: FloatArray, iterations: int = 3,
                  sigma: FloatArray | None = None) -> FloatArray:
    """Gauss-Newton on the points alone, the cameras held fixed (H&Z section 12.3's
    gold standard for each point, a 3x3 system per point).

    Parameters
    ----------
    point : (M,) int
        Point of each observation, ``0 <= point < len(X)``.
    xy : (M, 2)
        Pixels.
    R, t : (M, 3, 3), (M, 3)
        World-to-camera pose of each observation's camera.
    K : (3, 3)
    X : (P, 3)
        World points to start from.
    sigma : (M,), optional
        Relative standard deviation of each observation (the residuals are divided by
        it); None: all equal.

    Returns
    -------
    (P, 3) float64
        The points minimising their (weighted) squared reprojection errors; a point without
        observations, or whose system is singular, is returned as it came.
    """
    X = np.array(X, np.float64)
    P = len(X)
    for _ in range(iterations):
        cam = np.einsum("mij,mj->mi", R, X[point]) + t
        pix, J = project_with_jacobian(cam, K)
        J_point = J @ R  # (M, 2, 3)
        r = pix - xy
        if sigma is not None:
            J_point, r = J_point / sigma[:, None, None], r / sigma[:, None]
        H = _sum_rows(point, J_point.transpose(0, 2, 1) @ J_point, P)
        g = _sum_rows(point, np.einsum("mki,mk->mi", J_point, r), P)
        ok = np.abs(np.linalg.det(H)) > 1e-12 * np.maximum(np.einsum("pii->p", H), 1e-300) ** 3
        step = np.zeros((P, 3))
        step[ok] = np.linalg.solve(H[ok], g[ok][:, :, None])[:, :, 0]
        X -= step
    return X
