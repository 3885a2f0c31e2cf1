"""Synthetic scenes with known geometry, for tests, benchmarks and demos.

- :func:`asymmetric_camera` / :func:`asymmetric_pose`: a deliberately lopsided
  setup (fx != fy, off-centre principal point, oblique rotation, off-axis
  translation) so that a transposed matrix or a negated ``t`` cannot pass.
- :func:`render_planes`: ray-cast textured rectangles (a room corner with a box)
  seen by a pinhole camera.
- :func:`render_board`: a chessboard seen by a camera with lens distortion.
- :func:`lens_photo`: a photo as a lens with radial distortion would have taken it.
- :func:`orbit_scene` / :func:`orbit_poses`: a courtyard (tiled ground, walls, boxes)
  and any number of cameras circling it, for many-view tests and benchmarks.

Poses follow :mod:`scene3D.geometry`: ``x_cam = R X + t``.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import lru_cache

import cv2
import numpy as np

from ..geometry.conventions import FloatArray, rotation_about_axis, rotations_from_vectors


def asymmetric_camera(width: int = 640, height: int = 480) -> FloatArray:
    """Intrinsics with fx != fy and the principal point off centre.

    Parameters
    ----------
    width, height : int, default 640 and 480
        Image size (px).

    Returns
    -------
    (3, 3) float64 ndarray
    """
    return np.array([[0.82 * width * 1.25, 0.0, 0.52 * width],
                     [0.0, 0.80 * width * 1.25, 0.47 * height],
                     [0.0, 0.0, 1.0]])


def asymmetric_pose(angle_deg: float = 8.0, baseline: float = 1.0) -> tuple[FloatArray, FloatArray]:
    """``(R, t)`` of camera 2 (``x_cam2 = R x_cam1 + t``): oblique rotation, off-axis motion.

    Camera 2 sits at ``C2`` (mostly to the right, a little down and forward) and
    turns back towards the scene; ``|t| = baseline``.

    Parameters
    ----------
    angle_deg : float, default 8.0
        Rotation angle (deg).
    baseline : float, default 1.0
        ``|t|``.

    Returns
    -------
    R : (3, 3) float64 ndarray
    t : (3,) float64 ndarray
    """
    R = rotation_about_axis([0.25, 1.0, 0.12], angle_deg)
    center = np.array([1.0, 0.18, 0.25])
    center *= baseline / np.linalg.norm(center)
    return R, -R @ center


def random_points(n: int, seed: int = 0, depth: tuple[float, float] = (4.0, 9.0)) -> FloatArray:
    """``(n, 3)`` points spread in front of camera 1 (camera-1 frame).

    Parameters
    ----------
    n : int
        Number of points.
    seed : int, default 0
        Random seed.
    depth : (float, float), default (4.0, 9.0)
        Range of ``z``.

    Returns
    -------
    (n, 3) float64 ndarray
    """
    rng = np.random.default_rng(seed)
    z = rng.uniform(*depth, n)
    x = rng.uniform(-0.5, 0.5, n) * z
    y = rng.uniform(-0.4, 0.4, n) * z
    return np.column_stack([x, y, z])


@lru_cache(maxsize=256)
def texture(size: int = 512, seed: int = 0) -> np.ndarray:
    """A grey ``uint8`` texture with blobs at several scales and sharp-edged shapes (corners).

    Cached: the same ``(size, seed)`` returns the same read-only array.

    Parameters
    ----------
    size : int, default 512
        Side (px).
    seed : int, default 0
        Random seed.

    Returns
    -------
    (size, size) uint8 ndarray
    """
    rng = np.random.default_rng(seed)
    img = np.zeros((size, size), np.float32)
    for cells in (8, 16, 32, 64, 128):
        noise = rng.standard_normal((cells, cells)).astype(np.float32)
        img += cv2.resize(noise, (size, size), interpolation=cv2.INTER_CUBIC)
    img = 128.0 + 25.0 * img
    for _ in range(120):
        x, y = rng.integers(0, size, 2)
        r = int(rng.integers(4, size // 16))
        value = float(rng.integers(0, 256))
        if rng.random() < 0.5:
            cv2.circle(img, (int(x), int(y)), r, value, -1, cv2.LINE_AA)
        else:
            cv2.rectangle(img, (int(x), int(y)), (int(x) + r, int(y) + 2 * r // 3), value, -1)
    out = np.clip(img, 0, 255).astype(np.uint8)
    out.flags.writeable = False
    return out


@dataclass(frozen=True)
class Rectangle:
    """A textured rectangle ``origin + a u + b v`` with ``0 <= a, b <= 1`` (world frame)."""

    origin: tuple[float, float, float]
    u: tuple[float, float, float]
    v: tuple[float, float, float]
    seed: int = 0


def box_scene() -> list[Rectangle]:
    """A back wall, a floor and a box, in front of a camera at the origin looking along +z."""
    return [
        Rectangle((-8.0, -6.0, 12.0), (16.0, 0.0, 0.0), (0.0, 9.5, 0.0), seed=1),  # wall
        Rectangle((-8.0, 3.5, 3.0), (16.0, 0.0, 0.0), (0.0, 0.0, 9.0), seed=2),  # floor
        Rectangle((-2.5, 0.5, 6.0), (3.0, 0.0, 0.0), (0.0, 3.0, 0.0), seed=3),  # box front
        Rectangle((0.5, 0.5, 6.0), (0.0, 0.0, 2.5), (0.0, 3.0, 0.0), seed=4),  # box side
        Rectangle((-2.5, 0.5, 6.0), (3.0, 0.0, 0.0), (0.0, 0.0, 2.5), seed=5),  # box top
    ]


def orbit_scene() -> list[Rectangle]:
    """A courtyard around the origin (world y points down, the ground at ``y = 2``).

    A ground of 6 x 6 tiles (4 m each), eight walls 7 m high on a circle of radius 15 m,
    and three boxes near the centre; every face has its own texture, so that no two
    places look alike.
    """
    rects: list[Rectangle] = []
    seed = 100
    for a in range(6):
        for b in range(6):
            rects.append(Rectangle((-12.0 + 4 * a, 2.0, -12.0 + 4 * b), (4.0, 0, 0), (0, 0, 4.0),
                                   seed=seed))
            seed += 1
    for k in range(8):
        a0, a1 = 2 * np.pi * k / 8, 2 * np.pi * (k + 1) / 8
        p0 = np.array([15 * np.sin(a0), -5.0, -15 * np.cos(a0)])
        p1 = np.array([15 * np.sin(a1), -5.0, -15 * np.cos(a1)])
        rects.append(Rectangle(tuple(p0), tuple(p1 - p0), (0.0, 7.0, 0.0), seed=seed))
        seed += 1
    for (x, z, w, h, d) in ((-1.5, -1.5, 3.0, 3.0, 3.0), (2.5, 1.0, 1.5, 2.0, 1.5),
                            (-3.5, 2.0, 2.0, 1.2, 1.0)):
        top = 2.0 - h
        for origin, u, v in (((x, top, z), (w, 0, 0), (0, h, 0)),  # faces towards -z
                             ((x, top, z + d), (w, 0, 0), (0, h, 0)),  # +z
                             ((x, top, z), (0, 0, d), (0, h, 0)),  # -x
                             ((x + w, top, z), (0, 0, d), (0, h, 0)),  # +x
                             ((x, top, z), (w, 0, 0), (0, 0, d))):  # top
            rects.append(Rectangle(origin, u, v, seed=seed))
            seed += 1
    return rects


def orbit_poses(n: int, radius: float = 9.0) -> tuple[FloatArray, FloatArray]:
    """``n`` world-to-camera poses ``R (n, 3, 3)``, ``t (n, 3)`` circling :func:`orbit_scene`.

    Camera ``k`` stands at angle ``360 k / n`` deg on a wavy circle (radius and height
    vary), looking at the boxes; cameras are upright (image y along world y, down).

    Parameters
    ----------
    n : int
        Number of cameras.
    radius : float, default 9.0
        Mean radius of the circle.

    Returns
    -------
    R : (n, 3, 3) float64 ndarray
    t : (n, 3) float64 ndarray
    """
    angles = 2 * np.pi * np.arange(n) / n
    Rs, ts = np.empty((n, 3, 3)), np.empty((n, 3))
    down = np.array([0.0, 1.0, 0.0])
    for k, a in enumerate(angles):
        r = radius + 0.8 * np.cos(2 * a)
        center = np.array([r * np.sin(a), -0.6 + 0.4 * np.sin(3 * a), -r * np.cos(a)])
        z = np.array([0.0, 0.3, 0.0]) - center
        z /= np.linalg.norm(z)
        x = np.cross(down, z)
        x /= np.linalg.norm(x)
        y = np.cross(z, x)
        Rs[k] = np.stack([x, y, z])
        ts[k] = -Rs[k] @ center
    return Rs, ts


def outward_ring(num_cameras: int, points_per_camera: int = 270, seed: int = 0,
                 spacing: float = 0.5) -> tuple[FloatArray, FloatArray, FloatArray, np.ndarray,
                                                np.ndarray]:
    """Cameras on a ring looking outward (slightly tilted at random), each point in front of
    3 to 6 consecutive cameras: the banded covisibility of an orbit or a video, at any size.

    Parameters
    ----------
    num_cameras : int
        ``C`` cameras, ``spacing`` apart along the ring.
    points_per_camera : int, default 270
        Points per camera; each is seen 4.5 times on average, so a camera has about
        ``points_per_camera * 4.5 / 4`` observations.
    seed : int, default 0
        Random seed.
    spacing : float, default 0.5
        Distance between neighbouring cameras (world units).

    Returns
    -------
    R : (C, 3, 3) float64
        World-to-camera rotations.
    t : (C, 3) float64
        World-to-camera translations (``x_cam = R @ X + t``).
    X : (P, 3) float64
        The points, 4 to 10 units beyond the ring.
    view, point : (O,) int64
        The camera and the point of each observation.
    """
    rng = np.random.default_rng(seed)
    radius = num_cameras * spacing / (2 * np.pi)
    step = 2 * np.pi / num_cameras
    angles = step * np.arange(num_cameras)
    R, t = np.empty((num_cameras, 3, 3)), np.empty((num_cameras, 3))
    tilt = rotations_from_vectors(rng.normal(0, 0.02, (num_cameras, 3)))
    for k, a in enumerate(angles):
        z = np.array([np.cos(a), 0.0, np.sin(a)])
        y = np.array([0.0, 1.0, 0.0])
        R[k] = np.stack([np.cross(y, z), y, z]) @ tilt[k]
        t[k] = -R[k] @ (radius * z + rng.normal(0, 0.05, 3))
    num_points = num_cameras * points_per_camera // 4
    first = rng.integers(0, num_cameras, num_points)
    length = rng.integers(3, 7, num_points)
    a = angles[first] + ((length - 1) / 2 + rng.uniform(-0.5, 0.5, num_points)) * step
    r = radius + rng.uniform(4, 10, num_points)
    X = np.stack([r * np.cos(a), rng.uniform(-2, 2, num_points), r * np.sin(a)], axis=1)
    view = np.concatenate([(first + k) % num_cameras for k in range(6)])
    point = np.concatenate([np.arange(num_points)] * 6)
    keep = np.concatenate([k < length for k in range(6)])
    return R, t, X, view[keep], point[keep]


def _pixel_rays(K: FloatArray, size: tuple[int, int], supersample: int) -> FloatArray:
    w, h = size
    offsets = (np.arange(supersample) + 0.5) / supersample - 0.5
    xs = (np.arange(w)[:, None] + offsets[None, :]).ravel()
    ys = (np.arange(h)[:, None] + offsets[None, :]).ravel()
    gx, gy = np.meshgrid(xs, ys)
    pix = np.stack([gx, gy, np.ones_like(gx)], axis=-1)
    return pix @ np.linalg.inv(K).T  # (h*s, w*s, 3) camera-frame rays


def render_planes(
    K: FloatArray,
    R: FloatArray,
    t: FloatArray,
    size: tuple[int, int] = (640, 480),
    rectangles: list[Rectangle] | None = None,
    supersample: int = 2,
) -> tuple[np.ndarray, FloatArray]:
    """Ray-cast textured rectangles seen by the camera ``x_cam = R X + t``.

    Parameters
    ----------
    K : (3, 3) ndarray
        Intrinsics (OpenCV pixels).
    R, t : (3, 3), (3,) ndarray
        World-to-camera pose.
    size : (int, int), default (640, 480)
        ``(width, height)`` in px.
    rectangles : list of Rectangle or None, default None
        The scene; None for :func:`box_scene`.
    supersample : int, default 2
        Rays per pixel along each axis.


    Returns
    -------
    image : (H, W, 3) uint8
        BGR rendering (grey texture, tinted per rectangle); background black.
    depth : (H, W) float64
        z of the visible surface in the camera frame (inf for background).
    """
    rectangles = box_scene() if rectangles is None else rectangles
    w, h = size
    rays_cam = _pixel_rays(K, size, supersample)
    rays = rays_cam @ R  # world directions: R^T d, row-vector form
    center = -R.T @ np.reshape(t, 3)
    best = np.full(rays.shape[:2], np.inf)
    shade = np.zeros(rays.shape[:2] + (3,), np.float32)
    H, W = rays.shape[:2]
    for rect in rectangles:
        o, u, v = (np.asarray(a, dtype=np.float64) for a in (rect.origin, rect.u, rect.v))
        corners = np.array([o, o + u, o + v, o + u + v]) @ R.T + np.reshape(t, 3)
        if np.all(corners[:, 2] <= 0):
            continue  # behind the camera
        window = (slice(0, H), slice(0, W))
        if np.all(corners[:, 2] > 0):  # all in front: only its bounding box can see it
            pix = (corners @ K.T)[:, :2] / corners[:, 2:3] * supersample
            x0, y0 = np.floor(pix.min(axis=0)).astype(int) - 2
            x1, y1 = np.ceil(pix.max(axis=0)).astype(int) + 2
            x0, y0, x1, y1 = max(x0, 0), max(y0, 0), min(x1, W), min(y1, H)
            if x0 >= x1 or y0 >= y1:
                continue
            window = (slice(y0, y1), slice(x0, x1))
        r = rays[window]
        n = np.cross(u, v)
        denom = r @ n
        with np.errstate(divide="ignore", invalid="ignore"):
            s = ((o - center) @ n) / denom
        hit = center + s[..., None] * r - o
        a = hit @ u / (u @ u)
        b = hit @ v / (v @ v)
        visible = (s > 0) & (a >= 0) & (a <= 1) & (b >= 0) & (b <= 1) & (s < best[window])
        if not visible.any():
            continue
        tex = texture(512, rect.seed)
        # Sample the texture at the visible pixels only (the same values as a full map).
        count = int(visible.sum())
        rows = -(-count // 1024)
        map_a, map_b = np.zeros(rows * 1024, np.float32), np.zeros(rows * 1024, np.float32)
        map_a[:count], map_b[:count] = a[visible] * 511, b[visible] * 511
        sample = cv2.remap(tex, map_a.reshape(rows, 1024), map_b.reshape(rows, 1024),
                           cv2.INTER_LINEAR, borderMode=cv2.BORDER_REFLECT).ravel()[:count]
        tint = 0.6 + 0.4 * np.random.default_rng(rect.seed).random(3)
        best[window] = np.where(visible, s, best[window])
        shade[window][visible] = sample.astype(np.float32)[:, None] * tint[None, :]
    # Rays are (x, y, 1) in camera coordinates, so the ray parameter s is the depth.
    shade = shade.reshape(h, supersample, w, supersample, 3).mean(axis=(1, 3))
    depth = best.reshape(h, supersample, w, supersample)[:, supersample // 2, :, supersample // 2]
    return np.clip(shade + 0.5, 0, 255).astype(np.uint8), depth


def _board_plane_hits(
    K: FloatArray, dist: FloatArray, rvec: FloatArray, tvec: FloatArray,
    size: tuple[int, int], supersample: int,
) -> tuple[FloatArray, np.ndarray]:
    """Where each sub-pixel ray of a ``size`` image (``supersample`` x ``supersample``
    per pixel) meets the board plane ``z = 0``: board coordinates ``(h*s*w*s, 2)`` in
    row-major sub-pixel order, and whether the plane lies in front of the camera."""
    w, h = size
    offsets = (np.arange(supersample) + 0.5) / supersample - 0.5
    xs = (np.arange(w)[:, None] + offsets[None, :]).ravel()
    ys = (np.arange(h)[:, None] + offsets[None, :]).ravel()
    gx, gy = np.meshgrid(xs, ys)
    pix = np.stack([gx.ravel(), gy.ravel()], axis=1).reshape(-1, 1, 2)
    criteria = (cv2.TERM_CRITERIA_COUNT | cv2.TERM_CRITERIA_EPS, 50, 1e-10)
    norm = cv2.undistortPoints(pix, K, dist, None, None, None, criteria).reshape(-1, 2)
    rays = np.column_stack([norm, np.ones(len(norm))])
    R, _ = cv2.Rodrigues(np.asarray(rvec, dtype=np.float64))
    tvec = np.asarray(tvec, dtype=np.float64).reshape(3)
    # Board plane z_b = 0: points X = R [a, b, 0] + tvec; solve s ray = R [a b 0] + tvec.
    n = R[:, 2]
    s = (n @ tvec) / (rays @ n)
    hit = (s[:, None] * rays - tvec) @ R  # board coordinates
    return hit[:, :2], s > 0


def _grey_image(value: FloatArray, size: tuple[int, int], supersample: int) -> np.ndarray:
    w, h = size
    img = value.reshape(h, supersample, w, supersample).mean(axis=(1, 3))
    return np.clip(img + 0.5, 0, 255).astype(np.uint8)


def render_board(
    K: FloatArray,
    dist: FloatArray,
    rvec: FloatArray,
    tvec: FloatArray,
    inner_corners: tuple[int, int] = (9, 6),
    square_size: float = 1.0,
    size: tuple[int, int] = (640, 480),
    supersample: int = 3,
) -> np.ndarray:
    """Grey ``uint8`` image of a chessboard seen through a distorting lens.

    The board lies on ``z = 0`` of its frame with inner corner ``(i, j)`` at
    ``(i, j, 0) * square_size``; ``rvec, tvec`` map board to camera coordinates.
    A white margin of one square surrounds the squares.

    Parameters
    ----------
    K : (3, 3) ndarray
        Intrinsics (OpenCV pixels).
    dist : (n,) ndarray
        OpenCV distortion coefficients.
    rvec, tvec : (3,) ndarray
        Board-to-camera rotation vector and translation (``x_cam = R(rvec) X + tvec``).
    inner_corners : (int, int), default (9, 6)
        ``(columns, rows)`` of inner corners.
    square_size : float, default 1.0
        Side of a square, in the units of ``tvec``.
    size : (int, int), default (640, 480)
        ``(width, height)`` in px.
    supersample : int, default 3
        Samples per pixel along each axis.

    Returns
    -------
    (H, W) uint8 ndarray
    """
    hit, front = _board_plane_hits(K, dist, rvec, tvec, size, supersample)
    a = hit[:, 0] / square_size + 1.0  # squares from the outer board edge
    b = hit[:, 1] / square_size + 1.0
    cols, rows = inner_corners
    inside = (a >= 0) & (a < cols + 1) & (b >= 0) & (b < rows + 1) & front
    black = ((np.floor(a).astype(int) + np.floor(b).astype(int)) % 2 == 0) & inside
    margin = (a >= -1) & (a < cols + 2) & (b >= -1) & (b < rows + 2) & front
    value = np.where(black, 20.0, np.where(margin, 235.0, 120.0))
    return _grey_image(value, size, supersample)


def render_circles_board(
    K: FloatArray,
    dist: FloatArray,
    rvec: FloatArray,
    tvec: FloatArray,
    circles: tuple[int, int] = (4, 11),
    spacing: float = 1.0,
    asymmetric: bool = True,
    size: tuple[int, int] = (640, 480),
    supersample: int = 3,
) -> np.ndarray:
    """Grey ``uint8`` image of a grid of black circles on white, seen through a lens.

    Circle ``(j, i)`` (column, row) is centred at OpenCV's object point: ``(j, i, 0) *
    spacing`` for a symmetric grid, ``(2 j + i % 2, i, 0) * spacing`` for an asymmetric
    one (its rows offset by half a column); radius ``0.3 * spacing`` and ``0.5 *
    spacing``, with a white margin of two spacings around the centres.

    Parameters
    ----------
    K : (3, 3) ndarray
        Intrinsics (OpenCV pixels).
    dist : (n,) ndarray
        OpenCV distortion coefficients.
    rvec, tvec : (3,) ndarray
        Board-to-camera rotation vector and translation (``x_cam = R(rvec) X + tvec``).
    circles : (int, int), default (4, 11)
        ``(columns, rows)`` of circles.
    spacing : float, default 1.0
        Centre spacing, in the units of ``tvec``.
    asymmetric : bool, default True
        An asymmetric grid.
    size : (int, int), default (640, 480)
        ``(width, height)`` in px.
    supersample : int, default 3
        Samples per pixel along each axis.

    Returns
    -------
    (H, W) uint8 ndarray
    """
    hit, front = _board_plane_hits(K, dist, rvec, tvec, size, supersample)
    a, b = hit[:, 0] / spacing, hit[:, 1] / spacing
    cols, rows = circles
    row = np.clip(np.rint(b), 0, rows - 1)
    if asymmetric:
        # The nearest centre lies in the nearest row or a neighbour of it.
        best = np.full(len(a), np.inf)
        for dr in (-1, 0, 1):
            r = np.clip(row + dr, 0, rows - 1)
            shift = r % 2
            col = np.clip(np.rint((a - shift) / 2), 0, cols - 1)
            best = np.minimum(best, np.hypot(a - (2 * col + shift), b - r))
        radius, width = 0.5, 2 * cols - 1
    else:
        col = np.clip(np.rint(a), 0, cols - 1)
        best = np.hypot(a - col, b - row)
        radius, width = 0.3, cols
    margin = (a >= -2) & (a <= width + 1) & (b >= -2) & (b <= rows + 1) & front
    value = np.where((best <= radius) & front, 20.0, np.where(margin, 235.0, 120.0))
    return _grey_image(value, size, supersample)


def lens_photo(img: np.ndarray, K: FloatArray, k1: float) -> np.ndarray:
    """The photo ``img`` ``(H, W[, C])`` of a pinhole camera ``K`` ``(3, 3)`` as a lens with
    radial distortion ``k1`` (``r_d = r_u (1 + k1 r_u^2)`` in normalised coordinates
    about the principal point) would have taken it: the distortion the two-view
    distortion check looks for (:mod:`scene3D.twoview.distortion_fit`).

    Parameters
    ----------
    img : (H, W) or (H, W, C) ndarray
        The pinhole photo.
    K : (3, 3) ndarray
        Its intrinsics.
    k1 : float
        Radial coefficient.

    Returns
    -------
    (H, W) or (H, W, C) ndarray
    """
    h, w = img.shape[:2]
    xs, ys = np.meshgrid(np.arange(w, dtype=np.float64), np.arange(h, dtype=np.float64))
    xd, yd = (xs - K[0, 2]) / K[0, 0], (ys - K[1, 2]) / K[1, 1]
    xu, yu = xd.copy(), yd.copy()
    for _ in range(20):  # the undistorted point that the lens takes to each pixel
        r2 = xu**2 + yu**2
        xu, yu = xd / (1 + k1 * r2), yd / (1 + k1 * r2)
    return cv2.remap(img, (xu * K[0, 0] + K[0, 2]).astype(np.float32),
                     (yu * K[1, 1] + K[1, 2]).astype(np.float32), cv2.INTER_LINEAR)
