"""Depth maps fused into one cloud: normals, the multi-view consistency check, voxel thinning.

A pixel's depth is kept when at least ``min_agree`` other views agree with it: projected
into such a view, the point lands on a pixel whose own depth is within ``depth_tol`` (a
share of the depth) of the point's depth there, and whose point, projected back into the
first view, lands within ``reprojection_tol_px`` of the pixel it came from (the geometric
consistency of Schönberger et al., "Pixelwise View Selection for Unstructured Multi-View
Stereo", 2016, and of COLMAP's fusion). The kept point is the mean of its own and the
agreeing views' points, its normal and colour the means of theirs; the agreeing pixels are
not fused again when their own view's turn comes. The points of all views
are then thinned on a voxel grid: one point a voxel, the mean of those in it.

Frames as in :mod:`scene3D.geometry`: world-to-camera ``x_cam = R X + t``; depth maps hold
camera ``z``, NaN where there is none; normals are unit vectors facing the camera.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..geometry.conventions import FloatArray


@dataclass(frozen=True)
class ViewDepth:
    """One view's depth map with its camera.

    Attributes
    ----------
    depth : (H, W) float32
        Camera ``z`` of each pixel, NaN where there is none.
    normals : (H, W, 3) float32
        Unit normals in the camera frame (facing the camera), NaN where there is none.
    colors : (H, W, 3) uint8
        RGB of the view's image.
    K : (3, 3) float64
        Intrinsics of the depth map's pixels.
    R : (3, 3) float64
        World-to-camera rotation.
    t : (3,) float64
        World-to-camera translation.
    """

    depth: np.ndarray
    normals: np.ndarray
    colors: np.ndarray
    K: FloatArray
    R: FloatArray
    t: FloatArray

    @property
    def valid_pixels(self) -> int:
        """How many pixels have a depth."""
        return int(np.count_nonzero(np.isfinite(self.depth)))


@dataclass(frozen=True)
class DenseCloud:
    """A fused, thinned dense cloud in the model's world frame.

    Attributes
    ----------
    points3d : (N, 3) float64
        Points (world frame, the sparse model's units).
    colors : (N, 3) uint8
        RGB.
    normals : (N, 3) float32
        Unit normals (facing the cameras that saw the point).
    """

    points3d: FloatArray
    colors: np.ndarray
    normals: np.ndarray

    @property
    def num_points(self) -> int:
        return len(self.points3d)

    def __repr__(self) -> str:  # the arrays by their size: a cloud is 10^6 points
        return f"DenseCloud({self.num_points} points)"


def backproject(depth: np.ndarray, K: FloatArray) -> np.ndarray:
    """The camera-frame point ``(H, W, 3)`` of every pixel of ``depth`` ``(H, W)``
    (NaN where the depth is).

    Parameters
    ----------
    depth : (H, W) ndarray
        Camera ``z``.
    K : (3, 3) array_like
        Intrinsics.

    Returns
    -------
    (H, W, 3) float32 ndarray
    """
    h, w = depth.shape
    K = np.asarray(K, np.float64)
    x = ((np.arange(w) - K[0, 2]) / K[0, 0]).astype(np.float32)
    y = ((np.arange(h) - K[1, 2]) / K[1, 1]).astype(np.float32)
    z = depth.astype(np.float32)
    return np.stack([x[None, :] * z, y[:, None] * z, z], axis=-1)


def depth_normals(depth: np.ndarray, K: FloatArray, step_px: int = 3) -> np.ndarray:
    """Unit normals ``(H, W, 3)`` (camera frame, facing the camera) of a depth map
    ``(H, W)``, from the cross product of its central differences ``step_px`` pixels
    either side (wider steps average the depth noise out, narrower ones keep edges); NaN
    where a pixel or one of those four has no depth, and within ``step_px`` of the border.

    Parameters
    ----------
    depth : (H, W) ndarray
        Camera ``z``, NaN where none.
    K : (3, 3) array_like
        Intrinsics.
    step_px : int, default 3
        Half the span of the differences (px).

    Returns
    -------
    (H, W, 3) float32 ndarray
    """
    points = backproject(depth, K)
    normals = np.full(points.shape, np.nan, np.float32)
    s = step_px
    dx = points[s:-s, 2 * s:] - points[s:-s, :-2 * s]
    dy = points[2 * s:, s:-s] - points[:-2 * s, s:-s]
    n = np.cross(dx, dy)  # x right, y down: (dx x dy) points away from the camera
    with np.errstate(invalid="ignore", divide="ignore"):
        n = -n / np.linalg.norm(n, axis=-1, keepdims=True)
    normals[s:-s, s:-s] = n
    return normals


def project(points: FloatArray, K: FloatArray, R: FloatArray,
            t: FloatArray) -> tuple[FloatArray, FloatArray]:
    """Pixels ``(N, 2)`` and depths ``(N,)`` of world points ``(N, 3)`` in a pinhole
    camera ``K``, ``R``, ``t``.

    Parameters
    ----------
    points : (N, 3) array_like
        World points.
    K : (3, 3) array_like
    R : (3, 3) array_like
    t : (3,) array_like

    Returns
    -------
    pixels : (N, 2) ndarray
    depth : (N,) ndarray
    """
    cam = points @ np.asarray(R).T + np.asarray(t).reshape(3)
    z = cam[:, 2]
    with np.errstate(divide="ignore", invalid="ignore"):
        pix = (cam @ np.asarray(K).T)[:, :2] / z[:, None]
    return pix, z


def consistent_points(views: list[ViewDepth], v: int, others: list[int], depth_tol: float,
                      reprojection_tol_px: float, min_agree: int,
                      consumed: list[np.ndarray] | None = None,
                      ) -> tuple[FloatArray, np.ndarray, np.ndarray]:
    """The points of view ``v`` that at least ``min_agree`` of ``others`` agree with
    (module docstring), each the mean of its own and the agreeing views' points.

    With ``consumed`` (a ``(H, W)`` bool mask per view, updated in place), the pixels of
    ``v`` already marked are skipped, and the pixels of the other views that agreed with a
    kept point are marked: a surface point that several views see is then fused once,
    from the first of them, not once from each (as COLMAP's fusion does).

    Parameters
    ----------
    views : list of ViewDepth
    v : int
        The view whose pixels are checked.
    others : list of int
        The views they are checked against.
    depth_tol : float
        Largest depth difference, as a share of the depth.
    reprojection_tol_px : float
        Largest distance (px) between a pixel and its point seen from another view
        projected back.
    min_agree : int
        Least number of agreeing views.
    consumed : list of (H, W) bool ndarray or None, default None
        The pixels of each view fused already; None to use every pixel.

    Returns
    -------
    points3d : (N, 3) float64
        World points.
    colors : (N, 3) uint8
    normals : (N, 3) float32
        World-frame unit normals.
    """
    me = views[v]
    ys, xs = np.nonzero(np.isfinite(me.depth) if consumed is None
                        else np.isfinite(me.depth) & ~consumed[v])
    cam = backproject(me.depth, me.K)[ys, xs].astype(np.float64)
    world = (cam - me.t) @ me.R  # R^T (x - t)
    normal_sum = (me.normals[ys, xs].astype(np.float64) @ me.R)
    point_sum = world.copy()
    agree = np.zeros(len(world), np.int32)
    matched = []
    for u in others:
        other = views[u]
        h, w = other.depth.shape
        pix, z = project(world, other.K, other.R, other.t)
        px = np.rint(pix[:, 0])
        py = np.rint(pix[:, 1])
        inside = (z > 0) & (px >= 0) & (px < w) & (py >= 0) & (py < h)
        idx = np.nonzero(inside)[0]
        qx, qy = px[idx].astype(np.int64), py[idx].astype(np.int64)
        d = other.depth[qy, qx].astype(np.float64)
        ok = np.isfinite(d) & (np.abs(z[idx] - d) <= depth_tol * d)
        idx, qx, qy, d = idx[ok], qx[ok], qy[ok], d[ok]
        Kinv = np.linalg.inv(other.K)
        rays = np.column_stack([qx, qy, np.ones(len(qx))]) @ Kinv.T
        theirs = (rays * d[:, None] - other.t) @ other.R
        back, _ = project(theirs, me.K, me.R, me.t)
        near = np.hypot(back[:, 0] - xs[idx], back[:, 1] - ys[idx]) <= reprojection_tol_px
        idx, theirs, qx, qy = idx[near], theirs[near], qx[near], qy[near]
        agree[idx] += 1
        point_sum[idx] += theirs
        n = other.normals[qy, qx].astype(np.float64) @ other.R
        normal_sum[idx] += np.nan_to_num(n)
        matched.append((u, idx, qy, qx))
    keep = agree >= min_agree
    if consumed is not None:
        for u, idx, qy, qx in matched:
            used = keep[idx]
            consumed[u][qy[used], qx[used]] = True
    points = point_sum[keep] / (1 + agree[keep])[:, None]
    normals = np.nan_to_num(normal_sum[keep])
    length = np.linalg.norm(normals, axis=1, keepdims=True)
    normals = np.where(length > 0, normals / np.maximum(length, 1e-12), 0.0).astype(np.float32)
    return points, me.colors[ys[keep], xs[keep]], normals


def voxel_thin(points3d: FloatArray, colors: np.ndarray, normals: np.ndarray,
               voxel_size: float) -> DenseCloud:
    """One point per occupied voxel of side ``voxel_size``: the mean position, colour and
    (renormalised) normal of the points in it.

    Parameters
    ----------
    points3d : (N, 3) array_like
    colors : (N, 3) uint8 array_like
    normals : (N, 3) array_like
    voxel_size : float
        Side of a voxel (> 0, the points' units).

    Returns
    -------
    DenseCloud

    Raises
    ------
    ValueError
        ``voxel_size`` not positive.
    """
    if not voxel_size > 0:
        raise ValueError(f"`voxel_size` must be positive, got {voxel_size}")
    points3d = np.asarray(points3d, np.float64)
    if len(points3d) == 0:
        return DenseCloud(np.zeros((0, 3)), np.zeros((0, 3), np.uint8),
                          np.zeros((0, 3), np.float32))
    cells = np.floor((points3d - points3d.min(axis=0)) / voxel_size).astype(np.int64)
    span = cells.max(axis=0) + 1
    key = (cells[:, 0] * span[1] + cells[:, 1]) * span[2] + cells[:, 2]
    _, inverse, counts = np.unique(key, return_inverse=True, return_counts=True)
    inverse = inverse.ravel()

    def mean(values: np.ndarray) -> np.ndarray:
        return np.column_stack([np.bincount(inverse, values[:, i], len(counts))
                                for i in range(values.shape[1])]) / counts[:, None]

    normal = mean(np.asarray(normals, np.float64))
    length = np.linalg.norm(normal, axis=1, keepdims=True)
    normal = np.where(length > 0, normal / np.maximum(length, 1e-12), 0.0)
    color = np.clip(np.rint(mean(np.asarray(colors, np.float64))), 0, 255).astype(np.uint8)
    return DenseCloud(mean(points3d), color, normal.astype(np.float32))


def fuse_depth_maps(views: list[ViewDepth], voxel_size: float, depth_tol: float = 0.01,
                    reprojection_tol_px: float = 1.0, min_agree: int = 2,
                    check_views: list[list[int]] | None = None) -> DenseCloud:
    """The consistent points of every view (:func:`consistent_points`, each surface point
    once: a pixel that confirmed a kept point is not fused again), thinned on a voxel grid
    (:func:`voxel_thin`).

    Parameters
    ----------
    views : list of ViewDepth
    voxel_size : float
        Side of a voxel (the points' units); :func:`footprint` gives one.
    depth_tol : float, default 0.01
        Largest depth difference, as a share of the depth.
    reprojection_tol_px : float, default 1.0
        Largest reprojection distance (px).
    min_agree : int, default 2
        Least number of other views agreeing with a depth.
    check_views : list of list of int or None, default None
        For each view, the views it is checked against; None for all others.

    Returns
    -------
    DenseCloud
    """
    parts = []
    consumed = [np.zeros(view.depth.shape, bool) for view in views]
    for v in range(len(views)):
        others = [u for u in range(len(views)) if u != v] if check_views is None \
            else check_views[v]
        parts.append(consistent_points(views, v, others, depth_tol, reprojection_tol_px,
                                       min_agree, consumed))
    points = np.concatenate([p[0] for p in parts]) if parts else np.zeros((0, 3))
    colors = np.concatenate([p[1] for p in parts]) if parts else np.zeros((0, 3), np.uint8)
    normals = np.concatenate([p[2] for p in parts]) if parts else np.zeros((0, 3), np.float32)
    return voxel_thin(points, colors, normals, voxel_size)


def footprint(views: list[ViewDepth]) -> float:
    """The median size of a pixel on the surface: over the views, the median depth over
    the focal length (the points' units).

    Parameters
    ----------
    views : list of ViewDepth

    Returns
    -------
    float

    Raises
    ------
    ValueError
        No view has a depth.
    """
    sizes = [float(np.nanmedian(v.depth)) / float(np.sqrt(v.K[0, 0] * v.K[1, 1]))
             for v in views if v.valid_pixels]
    if not sizes:
        raise ValueError("no view has a depth to measure a pixel's footprint by")
    return float(np.median(sizes))
