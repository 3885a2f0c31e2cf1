"""Figures drawn with OpenCV into images at the working resolution (no matplotlib).

The command-line tools write these (fast to draw, fast to encode); the matplotlib
figures of :mod:`scene3D.viz.plotting` that the book's methods return show the same drawings,
so each figure is drawn by one function here. Every function returns a :class:`Raster`
(a BGR ``uint8`` image and its title) and never draws into its inputs.

Display conventions: images as cv2 loads them (BGR), pixels as in :mod:`scene3D.geometry`;
point colours RGB ``uint8`` as the reconstructions store them. 3D points in a camera
frame (``x`` right, ``y`` down, ``z`` forward) are shown with ``-y`` up.
"""

from __future__ import annotations

import colorsys
from dataclasses import dataclass

import cv2
import numpy as np

from ..geometry.conventions import FloatArray, camera_centers, require_whole_number
from ..geometry.epipolar import epipolar_lines
from ..geometry.rectification import RectifiedPair

__all__ = [
    "Raster", "draw_disparity", "draw_epipolar_lines", "draw_optic_flow", "draw_rectified",
    "encode_jpeg", "encode_png", "frustum_corners", "render_point_cloud", "robust_extent",
    "subsample_indices", "titled",
]

#: ``cv2.imencode`` parameters of the figures the commands write: zlib level 1 with
#: run-length matching and the "sub" row filter: twice as fast as level 1 alone, for a
#: file a little smaller (docs/benchmarks.md#default-run-figures-and-report).
PNG_FAST_PARAMS = (cv2.IMWRITE_PNG_COMPRESSION, 1, cv2.IMWRITE_PNG_STRATEGY,
                   cv2.IMWRITE_PNG_STRATEGY_RLE, cv2.IMWRITE_PNG_FILTER, cv2.IMWRITE_PNG_FILTER_SUB)
_FONT = cv2.FONT_HERSHEY_SIMPLEX


@dataclass(frozen=True)
class Raster:
    """A figure as an image.

    Attributes
    ----------
    image : (H, W, 3) uint8
        BGR.
    title : str
    """

    image: np.ndarray
    title: str


def subsample_indices(n: int, at_most: int) -> np.ndarray:
    """Indices of at most ``at_most`` of ``n`` items, evenly spaced (all of them when
    ``n <= at_most``): the same subset every time, spread over the whole list (a dense
    cloud is stored row by row, so this thins it evenly over the image).

    Parameters
    ----------
    n : int
        Number of items.
    at_most : int
        Most indices returned.

    Returns
    -------
    (min(n, at_most),) int ndarray
    """
    if n <= at_most:
        return np.arange(n)
    return (np.arange(max(at_most, 0), dtype=np.int64) * n) // max(at_most, 1)


def _bgr(img: np.ndarray) -> np.ndarray:
    if img.ndim == 2:
        return cv2.cvtColor(img, cv2.COLOR_GRAY2BGR)
    return img.copy()


def _point(p: np.ndarray) -> tuple[int, int]:
    """Integer pixel for cv2's drawing functions (which take integers; shift is 0)."""
    return int(round(float(p[0]))), int(round(float(p[1])))


def draw_optic_flow(img1: np.ndarray, pts1: FloatArray, pts2: FloatArray) -> Raster:
    """Arrows from each point of image 1 to its match in image 2, over image 1 in grey.

    Parameters
    ----------
    img1 : (H, W, 3) or (H, W) uint8 ndarray
        Image 1, BGR or grey.
    pts1, pts2 : (N, 2) array_like
        Matched pixels in images 1 and 2 (OpenCV convention).

    Returns
    -------
    Raster
    """
    grey = img1 if img1.ndim == 2 else cv2.cvtColor(img1, cv2.COLOR_BGR2GRAY)
    canvas = cv2.cvtColor(grey, cv2.COLOR_GRAY2BGR)
    for p, q in zip(np.asarray(pts1), np.asarray(pts2)):
        a, b = _point(p), _point(q)
        if a != b:
            cv2.arrowedLine(canvas, a, b, (0, 255, 255), 1, cv2.LINE_AA, tipLength=0.3)
    for p in np.asarray(pts1):
        cv2.circle(canvas, _point(p), 1, (0, 0, 255), -1, cv2.LINE_AA)
    return Raster(canvas, f"Optic flow: {len(pts1)} tracks (image 1 -> image 2)")


def epipolar_colors(count: int) -> np.ndarray:
    """``(count, 3)`` distinct bright colours (RGB in [0, 1]): hues a golden angle apart.

    Parameters
    ----------
    count : int
        Number of colours.

    Returns
    -------
    (count, 3) float64 ndarray
    """
    return np.array([colorsys.hsv_to_rgb((0.1 + 0.618034 * i) % 1.0, 0.85, 0.95)
                     for i in range(count)]).reshape(-1, 3)


def draw_epipolar_lines(img1: np.ndarray, img2: np.ndarray, F: FloatArray, pts1: FloatArray,
                        pts2: FloatArray, num_lines: int = 20) -> Raster:
    """Both images side by side with the epipolar lines of a few matches (``x2^T F x1 = 0``).

    Left: image 1 with the lines ``F^T x2`` and the points ``x1``; right: image 2 with
    the lines ``F x1`` and the points ``x2``.

    Parameters
    ----------
    img1, img2 : (H, W, 3) or (H, W) uint8 ndarray
        Images 1 and 2, BGR or grey.
    F : (3, 3) array_like
        Fundamental matrix, ``x2^T F x1 = 0``.
    pts1, pts2 : (N, 2) array_like
        Matched pixels in images 1 and 2.
    num_lines : int, default 20
        Number of matches drawn.

    Returns
    -------
    Raster
    """
    idx = subsample_indices(len(pts1), require_whole_number(num_lines, "num_lines"))
    colors = [tuple(int(255 * v) for v in c[::-1]) for c in epipolar_colors(len(idx))]
    panels = []
    for img, pts, lines in ((img1, np.asarray(pts1)[idx], epipolar_lines(F, pts2[idx], 2)),
                            (img2, np.asarray(pts2)[idx], epipolar_lines(F, pts1[idx], 1))):
        canvas = _bgr(img)
        w = canvas.shape[1]
        for (a, b, c), p, color in zip(lines, pts, colors):
            if abs(b) > 1e-9:
                y0, y1 = -c / b, -(a * (w - 1.0) + c) / b
                if max(abs(y0), abs(y1)) < 1e6:
                    cv2.line(canvas, (0, int(round(y0))), (w - 1, int(round(y1))), color, 1,
                             cv2.LINE_AA)
            cv2.circle(canvas, _point(p), 4, color, -1, cv2.LINE_AA)
        panels.append(canvas)
    gap = np.full((panels[0].shape[0], 8, 3), 255, np.uint8)
    return Raster(np.hstack([panels[0], gap, panels[1]]),
                  f"Epipolar lines of {len(idx)} matches: image 1 (left), image 2 (right)")


def draw_rectified(rectified: RectifiedPair, num_rows: int = 20) -> Raster:
    """The rectified images side by side with horizontal guide lines.

    Parameters
    ----------
    rectified : RectifiedPair
        The rectified images.
    num_rows : int, default 20
        Number of guide lines.

    Returns
    -------
    Raster
    """
    pair = np.hstack([_bgr(rectified.img1), _bgr(rectified.img2)])
    for y in np.linspace(0, pair.shape[0] - 1, num_rows + 2)[1:-1]:
        yi = int(round(y))
        cv2.line(pair, (0, yi), (pair.shape[1] - 1, yi), (0, 255, 0), 1, cv2.LINE_AA)
    return Raster(pair, "Rectified images (matches share a row)")


def draw_disparity(disparity: np.ndarray) -> Raster:
    """The disparity map (viridis, 1st to 99th percentile), invalid pixels (NaN) white, with
    a colour bar labelled in pixels on the right.

    Parameters
    ----------
    disparity : (H, W) ndarray
        Disparity map (px), NaN where invalid.

    Returns
    -------
    Raster
    """
    finite = np.isfinite(disparity)
    values = disparity[finite]
    lo, hi = (np.percentile(values, [1, 99]) if values.size else (0.0, 1.0))
    hi = hi if hi > lo else lo + 1.0
    scaled = np.zeros(disparity.shape, np.uint8)
    scaled[finite] = np.clip((values - lo) / (hi - lo) * 255, 0, 255).astype(np.uint8)
    canvas = cv2.applyColorMap(scaled, cv2.COLORMAP_VIRIDIS)
    canvas[~finite] = 255
    h = canvas.shape[0]
    bar = np.full((h, 90, 3), 255, np.uint8)
    ramp = np.linspace(255, 0, h - 20).astype(np.uint8)[:, None].repeat(20, axis=1)
    bar[10:h - 10, 8:28] = cv2.applyColorMap(ramp, cv2.COLORMAP_VIRIDIS)
    for frac in (0.0, 0.5, 1.0):
        y = int(10 + (1 - frac) * (h - 21))
        cv2.putText(bar, f"{lo + frac * (hi - lo):.0f}", (32, y + 5), _FONT, 0.45, (0, 0, 0), 1,
                    cv2.LINE_AA)
    cv2.putText(bar, "px", (32, h // 2 + 30), _FONT, 0.45, (0, 0, 0), 1, cv2.LINE_AA)
    return Raster(np.hstack([canvas, bar]),
                  f"Disparity of rectified image 1 ({values.size / disparity.size:.0%} valid)")


def frustum_corners(R: FloatArray, t: FloatArray, K: FloatArray, image_size: tuple[int, int],
                    depth: float) -> FloatArray:
    """World positions ``(V, 5, 3)`` of each camera's centre and its image corners at
    ``depth`` along the optical axis (the frustum to draw), poses ``x_cam = R X + t``.
    Views with NaN poses give NaN.

    Parameters
    ----------
    R : (V, 3, 3) array_like
        World-to-camera rotations.
    t : (V, 3) array_like
        World-to-camera translations.
    K : (3, 3) array_like
        Intrinsics (OpenCV pixels).
    image_size : (int, int)
        ``(width, height)`` in px.
    depth : float
        Distance of the corners along the optical axis, in world units.

    Returns
    -------
    (V, 5, 3) float64 ndarray
    """
    R = np.asarray(R, dtype=np.float64).reshape(-1, 3, 3)
    t = np.asarray(t, dtype=np.float64).reshape(-1, 3)
    w, h = image_size
    corners = np.array([[-0.5, -0.5, 1], [w - 0.5, -0.5, 1], [w - 0.5, h - 0.5, 1],
                        [-0.5, h - 0.5, 1]], dtype=np.float64)
    rays = corners @ np.linalg.inv(K).T * depth  # camera frame
    centers = camera_centers(R, t)
    world = np.einsum("nj,vjk->vnk", rays, R) + centers[:, None, :]  # R^T x + C
    return np.concatenate([centers[:, None, :], world], axis=1)


def robust_extent(points3d: FloatArray) -> tuple[FloatArray, FloatArray]:
    """Lower and upper corners ``(3,), (3,)`` of the 2nd to 98th percentile box of the points
    (nearest rank; a few far points do not flatten a view). An empty set gives the unit box.

    Parameters
    ----------
    points3d : (N, 3) array_like
        Points.

    Returns
    -------
    low, high : (3,) float64 ndarray
    """
    points3d = np.asarray(points3d, dtype=np.float64).reshape(-1, 3)
    n = len(points3d)
    if n == 0:
        return np.zeros(3), np.ones(3)
    k_lo, k_hi = int(round(0.02 * (n - 1))), int(round(0.98 * (n - 1)))
    part = np.partition(points3d, (k_lo, k_hi), axis=0)  # np.percentile imports numpy.ma
    return part[k_lo].copy(), part[k_hi].copy()


def render_point_cloud(
    points3d: FloatArray,
    colors: np.ndarray | None = None,
    frusta: FloatArray | None = None,
    size: tuple[int, int] = (960, 720),
    yaw_deg: float = -35.0,
    pitch_deg: float = 25.0,
    title: str | None = None,
) -> Raster:
    """A view of a coloured point cloud (and camera frusta) from above and to one side.

    A virtual pinhole camera looks at the centre of the points' 2nd to 98th percentile box
    (grown to hold the frusta) from ``yaw_deg`` around the vertical and ``pitch_deg`` above
    the frame's ``z`` axis, far enough for the box to fit; nearer points hide farther ones
    (a z-buffer), each drawn as a square whose size shrinks with the number of points.

    Parameters
    ----------
    points3d : (N, 3) float64
        In a camera frame (x right, y down, z forward).
    colors : (N, 3) uint8, optional
        RGB (grey when absent).
    frusta : (V, 5, 3) float64, optional
        :func:`frustum_corners`, drawn in red.
    size : tuple[int, int]
        (width, height) of the image.
    """
    points3d = np.asarray(points3d, dtype=np.float64).reshape(-1, 3)
    w, h = size
    canvas = np.full((h, w, 3), 245, np.uint8)
    lo, hi = robust_extent(points3d)
    if frusta is not None and np.isfinite(frusta).any():
        finite = np.asarray(frusta, dtype=np.float64).reshape(-1, 3)
        finite = finite[np.all(np.isfinite(finite), axis=1)]
        lo, hi = np.minimum(lo, finite.min(axis=0)), np.maximum(hi, finite.max(axis=0))
    center = 0.5 * (lo + hi)
    radius = max(0.5 * float(np.linalg.norm(hi - lo)), 1e-9)
    yaw, pitch = np.radians(yaw_deg), np.radians(pitch_deg)
    forward = np.array([np.sin(yaw) * np.cos(pitch), np.sin(pitch), np.cos(yaw) * np.cos(pitch)])
    right = np.cross([0.0, 1.0, 0.0], forward)
    right /= np.linalg.norm(right)
    down = np.cross(forward, right)
    R_v = np.stack([right, down, forward])
    focal = 0.5 * min(w, h) / np.tan(np.radians(25.0))
    distance = radius / np.tan(np.radians(25.0))
    t_v = -R_v @ (center - distance * forward)
    K_v = np.array([[focal, 0, (w - 1) / 2], [0, focal, (h - 1) / 2], [0, 0, 1.0]])

    def project(X: FloatArray) -> tuple[FloatArray, FloatArray]:
        cam = X @ R_v.T + t_v
        z = cam[:, 2]
        with np.errstate(divide="ignore", invalid="ignore"):
            uv = (cam @ K_v.T)[:, :2] / z[:, None]
        return uv, z

    if len(points3d):
        rgb = (np.full((len(points3d), 3), 128, np.uint8) if colors is None
               else np.asarray(colors, dtype=np.uint8).reshape(-1, 3))
        uv, z = project(points3d)
        ok = (z > 1e-9) & np.all(np.isfinite(uv), axis=1)
        splat = 5 if ok.sum() < 5000 else 3 if ok.sum() < 50000 else 2
        ui = np.rint(uv[ok, 0]).astype(np.int64)
        vi = np.rint(uv[ok, 1]).astype(np.int64)
        zs, bgr = z[ok], rgb[ok][:, ::-1]
        offsets = np.arange(splat) - splat // 2
        du, dv = (a.ravel() for a in np.meshgrid(offsets, offsets))
        uu = (ui[:, None] + du[None, :]).ravel()
        vv = (vi[:, None] + dv[None, :]).ravel()
        zz = np.repeat(zs, len(du))
        owner = np.repeat(np.arange(len(zs)), len(du))
        inside = (uu >= 0) & (uu < w) & (vv >= 0) & (vv < h)
        flat, zz, owner = vv[inside] * w + uu[inside], zz[inside], owner[inside]
        zbuffer = np.full(w * h, np.inf)
        np.minimum.at(zbuffer, flat, zz)
        nearest = zz <= zbuffer[flat]
        canvas.reshape(-1, 3)[flat[nearest]] = bgr[owner[nearest]]
    drawn = 0
    if frusta is not None:
        for corners in np.asarray(frusta, dtype=np.float64):
            if not np.all(np.isfinite(corners)):
                continue
            uv, z = project(corners)
            if np.any(z <= 1e-9):
                continue
            pts = [_point(p) for p in uv]
            for k in range(1, 5):
                cv2.line(canvas, pts[0], pts[k], (40, 40, 220), 1, cv2.LINE_AA)
                cv2.line(canvas, pts[k], pts[1 + k % 4], (40, 40, 220), 1, cv2.LINE_AA)
            drawn += 1
    if title is None:
        title = f"Point cloud: {len(points3d)} points" + (f", {drawn} cameras" if drawn else "")
    return Raster(canvas, title)


def titled(raster: Raster, band_px: int = 30) -> np.ndarray:
    """The raster's image with its title written in a white band above it.

    Parameters
    ----------
    raster : Raster
        A BGR drawing and its title.
    band_px : int, default 30
        Height of the title band (px).

    Returns
    -------
    (band_px + H, W, 3) uint8 ndarray
    """
    img = raster.image
    band = np.full((band_px, img.shape[1], 3), 255, np.uint8)
    scale = 0.6
    (text_w, _), _ = cv2.getTextSize(raster.title, _FONT, scale, 1)
    if text_w > img.shape[1] - 16:
        scale *= (img.shape[1] - 16) / text_w
    cv2.putText(band, raster.title, (8, band_px - 10), _FONT, scale, (0, 0, 0), 1, cv2.LINE_AA)
    return np.vstack([band, img])


def encode_png(image: np.ndarray, fast: bool = True) -> bytes:
    """PNG bytes of a BGR (or grey) ``uint8`` image (``cv2.imencode``, which releases the
    GIL); ``fast`` uses :data:`PNG_FAST_PARAMS`, otherwise OpenCV's defaults.

    Parameters
    ----------
    image : (H, W, 3) or (H, W) uint8 ndarray
        BGR or grey image.
    fast : bool, default True
        Fast compression.

    Returns
    -------
    bytes

    Raises
    ------
    ValueError
        If OpenCV cannot encode it.
    """
    ok, buffer = cv2.imencode(".png", image, list(PNG_FAST_PARAMS) if fast else [])
    if not ok:
        raise ValueError("cv2.imencode could not encode the image as PNG")
    return buffer.tobytes()


def encode_jpeg(image: np.ndarray, quality: int = 90) -> bytes:
    """JPEG bytes of a BGR (or grey) ``uint8`` image (for embedding in a report: a tenth
    of the PNG's size for photographs).

    Parameters
    ----------
    image : (H, W, 3) or (H, W) uint8 ndarray
        BGR or grey image.
    quality : int, default 90
        JPEG quality, 0 to 100.

    Returns
    -------
    bytes

    Raises
    ------
    ValueError
        If OpenCV cannot encode it.
    """
    ok, buffer = cv2.imencode(".jpg", image, [cv2.IMWRITE_JPEG_QUALITY, int(quality)])
    if not ok:
        raise ValueError("cv2.imencode could not encode the image as JPEG")
    return buffer.tobytes()
