"""The alternative depth map: the two-view dense matcher (:mod:`scene3D.dense`,
rectified semi-global matching) against each neighbour, the results merged.

Each neighbour's pair is rectified and matched by :func:`scene3D.dense.dense_point_cloud`
over the disparities of the reference's depth range (pixel pairs at the near and far
depths stand in for sparse matches); its points, in the reference camera frame, are
projected into the reference view (the nearest point where several land on one pixel).
A pixel's depth is the median over the neighbours that give it one, kept where at least
two agree within ``agree`` of it (or where only one neighbour was matched). It needs the
reference and its neighbours to share one camera matrix, as the rectification does.
docs/dense.md compares it with the plane sweep (:mod:`scene3D.densify.sweep`).
"""

from __future__ import annotations

import logging

import numpy as np

from ..dense import dense_point_cloud
from ..errors import ReconstructionError
from ..geometry.conventions import FloatArray

logger = logging.getLogger(__name__)


def range_pixels(K: FloatArray, R: FloatArray, t: FloatArray, size: tuple[int, int],
                 depth_range: tuple[float, float]) -> tuple[FloatArray, FloatArray]:
    """Pixel pairs ``(N, 2)``, ``(N, 2)`` of a grid of reference pixels at the near and far
    depths and where they project in the neighbour (``x_nb = R x_ref + t``): what the
    two-view matcher takes its disparity range from.

    Parameters
    ----------
    K : (3, 3) array_like
        The shared intrinsics.
    R, t : (3, 3), (3,) array_like
        The neighbour's pose relative to the reference.
    size : (int, int)
        ``(width, height)``.
    depth_range : (float, float)
        ``(near, far)``.

    Returns
    -------
    ref : (N, 2) ndarray
    nb : (N, 2) ndarray
    """
    w, h = size
    xs, ys = np.meshgrid(np.linspace(0, w - 1, 9), np.linspace(0, h - 1, 7))
    pix = np.column_stack([xs.ravel(), ys.ravel(), np.ones(xs.size)])
    rays = pix @ np.linalg.inv(K).T
    refs, nbs = [], []
    for z in depth_range:
        cam = (rays * z) @ np.asarray(R).T + np.asarray(t).reshape(3)
        ok = cam[:, 2] > 0
        proj = (cam[ok] @ np.asarray(K).T)
        refs.append(pix[ok, :2])
        nbs.append(proj[:, :2] / proj[:, 2:3])
    return np.concatenate(refs), np.concatenate(nbs)


def sgbm_depth(reference: np.ndarray, K: FloatArray, neighbours: list[tuple],
               depth_range: tuple[float, float], agree: float = 0.01) -> np.ndarray:
    """The depth map ``(H, W)`` of ``reference`` ``(H, W, 3)`` BGR from rectified SGBM
    against each neighbour (module docstring), NaN where none.

    Parameters
    ----------
    reference : (H, W, 3) uint8 ndarray
        The undistorted reference image.
    K : (3, 3) array_like
        The intrinsics of it and of every neighbour.
    neighbours : list of (image, R, t)
        Each neighbour's undistorted image ``(H, W, 3)`` and pose relative to the
        reference (``x_nb = R x_ref + t``).
    depth_range : (float, float)
        ``(near, far)``.
    agree : float, default 0.01
        Largest relative difference of two neighbours' depths that agree.

    Returns
    -------
    (H, W) float32 ndarray
    """
    h, w = reference.shape[:2]
    K = np.asarray(K, np.float64)
    maps = []
    for img, R, t in neighbours:
        ref_pix, nb_pix = range_pixels(K, R, t, (w, h), depth_range)
        try:
            dense = dense_point_cloud(reference, img, K, R, t, ref_pix, nb_pix)
        except ReconstructionError as exc:  # a pair rectification cannot serve
            logger.info("SGBM neighbour left out: %s", exc)
            continue
        cam = dense.points3d
        proj = cam @ K.T
        z = cam[:, 2]
        front = z > 0
        px = np.rint(proj[front, 0] / z[front]).astype(np.int64)
        py = np.rint(proj[front, 1] / z[front]).astype(np.int64)
        z = z[front]
        inside = (px >= 0) & (px < w) & (py >= 0) & (py < h)
        depth = np.full(h * w, np.inf)
        np.minimum.at(depth, py[inside] * w + px[inside], z[inside])
        maps.append(np.where(np.isfinite(depth), depth, np.nan).reshape(h, w))
    if not maps:
        return np.full((h, w), np.nan, np.float32)
    stack = np.stack(maps)
    with np.errstate(all="ignore"):
        median = np.nanmedian(stack, axis=0)
        agreeing = np.sum(np.abs(stack - median) <= agree * median, axis=0)
    keep = np.isfinite(median) & ((agreeing >= 2) | (len(maps) == 1))
    return np.where(keep, median, np.nan).astype(np.float32)
