"""Dense clouds against a known surface: accuracy and completeness as ETH3D reports them.

- accuracy at a tolerance: the share of the cloud's points within the tolerance of the
  true surface (:func:`rectangle_distances`, exact for :mod:`scene3D.evaluation.synthetic`'s
  scenes);
- completeness at a tolerance: the share of points sampled on the true surface (what the
  cameras see: their exact depth maps back-projected) within the tolerance of a point of
  the cloud (:func:`within_distance`, exact).

Schöps et al., "A Multi-View Stereo Benchmark with High-Resolution Images and Multi-Camera
Videos", CVPR 2017, section 5.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..geometry.conventions import FloatArray
from .synthetic import Rectangle


@dataclass(frozen=True)
class DenseScore:
    """Accuracy and completeness of a cloud at one tolerance.

    Attributes
    ----------
    tolerance : float
        The distance (the scene's units).
    accuracy : float
        Share of the cloud's points within ``tolerance`` of the true surface.
    completeness : float
        Share of the true surface's samples within ``tolerance`` of the cloud.
    """

    tolerance: float
    accuracy: float
    completeness: float

    @property
    def f1(self) -> float:
        """The harmonic mean of accuracy and completeness (ETH3D's F1 score)."""
        total = self.accuracy + self.completeness
        return 0.0 if total == 0 else 2 * self.accuracy * self.completeness / total


def rectangle_distances(points3d: FloatArray, rectangles: list[Rectangle]) -> FloatArray:
    """The distance ``(N,)`` of each point ``(N, 3)`` to the nearest of ``rectangles``
    (each ``origin + a u + b v``, ``0 <= a, b <= 1``, with ``u`` perpendicular to ``v``,
    as all of :mod:`scene3D.evaluation.synthetic`'s are).

    Parameters
    ----------
    points3d : (N, 3) array_like
        Points in the scene's world frame.
    rectangles : list of Rectangle

    Returns
    -------
    (N,) float64 ndarray
    """
    points3d = np.asarray(points3d, np.float64).reshape(-1, 3)
    best = np.full(len(points3d), np.inf)
    for rect in rectangles:
        o, u, v = (np.asarray(x, np.float64) for x in (rect.origin, rect.u, rect.v))
        d = points3d - o
        a = np.clip(d @ u / (u @ u), 0.0, 1.0)
        b = np.clip(d @ v / (v @ v), 0.0, 1.0)
        nearest = o + a[:, None] * u + b[:, None] * v
        best = np.minimum(best, np.linalg.norm(points3d - nearest, axis=1))
    return best


def within_distance(queries: FloatArray, points3d: FloatArray, tolerance: float) -> np.ndarray:
    """Whether each query ``(M, 3)`` has a point of ``points3d`` ``(N, 3)`` within
    ``tolerance`` (exact: a grid of cells ``tolerance / sqrt(3)`` across, a query settled at
    once when its own cell holds a point, the others against every point of the cells
    within reach).

    Parameters
    ----------
    queries : (M, 3) array_like
    points3d : (N, 3) array_like
    tolerance : float
        The distance (> 0).

    Returns
    -------
    (M,) bool ndarray
    """
    queries = np.asarray(queries, np.float64).reshape(-1, 3)
    points3d = np.asarray(points3d, np.float64).reshape(-1, 3)
    found = np.zeros(len(queries), bool)
    if len(points3d) == 0 or len(queries) == 0:
        return found
    cell = tolerance / np.sqrt(3.0)
    reach = int(np.ceil(tolerance / cell))
    low = np.minimum(points3d.min(axis=0), queries.min(axis=0)) - (reach + 1) * cell
    span = np.floor((np.maximum(points3d.max(axis=0), queries.max(axis=0)) - low)
                    / cell).astype(np.int64) + reach + 2

    def keys(cells: np.ndarray) -> np.ndarray:
        return (cells[:, 0] * span[1] + cells[:, 1]) * span[2] + cells[:, 2]

    p_cells = np.floor((points3d - low) / cell).astype(np.int64)
    order = np.argsort(keys(p_cells), kind="stable")
    sorted_keys = keys(p_cells)[order]
    sorted_points = points3d[order]
    q_cells = np.floor((queries - low) / cell).astype(np.int64)
    own = keys(q_cells)
    start = np.searchsorted(sorted_keys, own, "left")
    found = np.searchsorted(sorted_keys, own, "right") > start
    offsets = np.array([(i, j, k) for i in range(-reach, reach + 1)
                        for j in range(-reach, reach + 1) for k in range(-reach, reach + 1)])
    for offset in offsets:
        left = np.nonzero(~found)[0]
        if len(left) == 0:
            break
        key = keys(q_cells[left] + offset)
        first = np.searchsorted(sorted_keys, key, "left")
        count = np.searchsorted(sorted_keys, key, "right") - first
        for rank in range(int(count.max(initial=0))):
            has = count > rank
            idx = left[has]
            gap = np.linalg.norm(sorted_points[first[has] + rank] - queries[idx], axis=1)
            found[idx[gap <= tolerance]] = True
    return found


def score_dense_cloud(points3d: FloatArray, rectangles: list[Rectangle],
                      surface_samples: FloatArray, tolerances: list[float]) -> list[DenseScore]:
    """Accuracy and completeness of a cloud at each tolerance (module docstring).

    Parameters
    ----------
    points3d : (N, 3) array_like
        The cloud (the scene's world frame).
    rectangles : list of Rectangle
        The true surface.
    surface_samples : (M, 3) array_like
        Points on the true surface that the cameras see.
    tolerances : list of float
        Distances (the scene's units).

    Returns
    -------
    list of DenseScore
    """
    distances = rectangle_distances(points3d, rectangles)
    return [DenseScore(float(tol), float(np.mean(distances <= tol)) if len(distances) else 0.0,
                       float(np.mean(within_distance(surface_samples, points3d, tol))))
            for tol in tolerances]


@dataclass(frozen=True)
class RenderedViews:
    """Views of :func:`~scene3D.evaluation.synthetic.orbit_scene` with their exact geometry
    (:func:`render_orbit_views`).

    Attributes
    ----------
    images : list of (H, W, 3) uint8
        BGR renderings.
    depths : list of (H, W) float64
        Their exact depth (camera ``z``, inf on the background).
    K : (3, 3) float64
    R : (V, 3, 3) float64
        World-to-camera rotations.
    t : (V, 3) float64
    rectangles : list of Rectangle
        The scene.
    sparse_points : (P, 3) float64
        Surface points seen by at least two views (a sparse model's points).
    obs_view, obs_point : (O,) int
        Which view sees which of them.
    obs_xy : (O, 2) float64
        Where (OpenCV pixels).
    """

    images: list[np.ndarray]
    depths: list[np.ndarray]
    K: FloatArray
    R: FloatArray
    t: FloatArray
    rectangles: list[Rectangle]
    sparse_points: FloatArray
    obs_view: np.ndarray
    obs_point: np.ndarray
    obs_xy: FloatArray

    def surface_samples(self, step: int = 2, min_views: int = 1) -> FloatArray:
        """Points ``(M, 3)`` of the true surface that at least ``min_views`` of the views
        see: every ``step``-th pixel's exact depth back-projected, world frame.

        Parameters
        ----------
        step : int, default 2
            Every ``step``-th pixel along each axis.
        min_views : int, default 1
            Least number of views that see a sample unoccluded (:meth:`views_seeing`).

        Returns
        -------
        (M, 3) float64 ndarray
        """
        out = []
        Kinv = np.linalg.inv(self.K)
        for depth, R, t in zip(self.depths, self.R, self.t):
            ys, xs = np.mgrid[0:depth.shape[0]:step, 0:depth.shape[1]:step]
            z = depth[ys, xs]
            ok = np.isfinite(z)
            rays = np.column_stack([xs[ok], ys[ok], np.ones(ok.sum())]) @ Kinv.T
            out.append((rays * z[ok][:, None] - t) @ R)
        samples = np.concatenate(out)
        return samples if min_views <= 1 else samples[self.views_seeing(samples) >= min_views]

    def views_seeing(self, points3d: FloatArray) -> np.ndarray:
        """How many of the views see each surface point ``(N, 3)`` unoccluded: it projects
        into the image and its depth there is the rendered one (to 0.2 %).

        Parameters
        ----------
        points3d : (N, 3) array_like
            Points on the surface (world frame).

        Returns
        -------
        (N,) int ndarray
        """
        points3d = np.asarray(points3d, np.float64).reshape(-1, 3)
        counts = np.zeros(len(points3d), int)
        for depth, R, t in zip(self.depths, self.R, self.t):
            h, w = depth.shape
            cam = points3d @ R.T + t
            with np.errstate(divide="ignore", invalid="ignore"):
                pix = (cam @ self.K.T)[:, :2] / cam[:, 2:3]
            px = np.rint(np.nan_to_num(pix[:, 0], nan=-1)).astype(np.int64)
            py = np.rint(np.nan_to_num(pix[:, 1], nan=-1)).astype(np.int64)
            inside = (cam[:, 2] > 0) & (px >= 0) & (px < w) & (py >= 0) & (py < h)
            seen = np.zeros(len(points3d), bool)
            seen[inside] = np.abs(depth[py[inside], px[inside]] - cam[inside, 2]) \
                <= 2e-3 * cam[inside, 2]
            counts += seen
        return counts


def render_orbit_views(views: int, size: tuple[int, int] = (640, 480), arc_deg: float = 90.0,
                       points_per_view: int = 400, seed: int = 0) -> RenderedViews:
    """``views`` renderings of the courtyard (:func:`~scene3D.evaluation.synthetic.orbit_scene`)
    from cameras spread over ``arc_deg`` of :func:`~scene3D.evaluation.synthetic.orbit_poses`'
    circle, with exact depth and a sparse model's points (random pixels of each view,
    kept where at least two views see them unoccluded).

    Parameters
    ----------
    views : int
        Number of cameras.
    size : (int, int), default (640, 480)
        ``(width, height)`` (px).
    arc_deg : float, default 90.0
        The part of the circle the cameras cover (deg).
    points_per_view : int, default 400
        Sparse points sampled in each view.
    seed : int, default 0
        Random seed.

    Returns
    -------
    RenderedViews
    """
    from .synthetic import asymmetric_camera, orbit_poses, orbit_scene, render_planes

    K = asymmetric_camera(*size)
    full = int(round(views * 360.0 / arc_deg))
    R_all, t_all = orbit_poses(full)
    R, t = R_all[:views], t_all[:views]
    scene = orbit_scene()
    images, depths = [], []
    for k in range(views):
        img, depth = render_planes(K, R[k], t[k], size, scene)
        images.append(img)
        depths.append(depth)
    rng = np.random.default_rng(seed)
    Kinv = np.linalg.inv(K)
    points = []
    for k in range(views):
        xs = rng.integers(0, size[0], points_per_view)
        ys = rng.integers(0, size[1], points_per_view)
        z = depths[k][ys, xs]
        ok = np.isfinite(z)
        rays = np.column_stack([xs[ok], ys[ok], np.ones(ok.sum())]) @ Kinv.T
        points.append((rays * z[ok][:, None] - t[k]) @ R[k])
    X = np.concatenate(points)
    obs = []
    for k in range(views):
        cam = X @ R[k].T + t[k]
        pix = (cam @ K.T)[:, :2] / cam[:, 2:3]
        px, py = np.rint(pix[:, 0]).astype(int), np.rint(pix[:, 1]).astype(int)
        inside = (cam[:, 2] > 0) & (px >= 0) & (px < size[0]) & (py >= 0) & (py < size[1])
        seen = np.zeros(len(X), bool)
        seen[inside] = np.abs(depths[k][py[inside], px[inside]] - cam[inside, 2]) \
            <= 1e-3 * cam[inside, 2]
        obs.append((k, np.nonzero(seen)[0], pix[seen]))
    counts = np.zeros(len(X), int)
    for _, idx, _ in obs:
        counts[idx] += 1
    keep = counts >= 2
    new = np.cumsum(keep) - 1
    obs_view = np.concatenate([np.full(keep[idx].sum(), k) for k, idx, _ in obs])
    obs_point = np.concatenate([new[idx[keep[idx]]] for _, idx, _ in obs])
    obs_xy = np.concatenate([xy[keep[idx]] for _, idx, xy in obs])
    return RenderedViews(images, depths, K, R, t, scene, X[keep], obs_view, obs_point, obs_xy)
