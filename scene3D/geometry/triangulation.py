"""Two-view triangulation, reprojection errors and parallax (H&Z section 12.2).

Points are returned in the camera-1 frame: camera 1 is ``[I | 0]`` and camera 2
is ``[R | t]`` with ``x_cam2 = R x_cam1 + t``.
"""

from __future__ import annotations

import cv2
import numpy as np
from numpy.typing import ArrayLike

from .conventions import (
    FloatArray,
    as_points2d,
    check_same_length,
    median,
    project,
    projection_matrix,
)


def triangulate_points(
    pts1: ArrayLike, pts2: ArrayLike, K: ArrayLike, R: ArrayLike, t: ArrayLike
) -> FloatArray:
    """Linear (DLT) triangulation of correspondences.

    Parameters
    ----------
    pts1, pts2 : (N, 2) array_like
        Pixels in image 1 and image 2.
    K : (3, 3) array_like
        Intrinsics shared by both views.
    R, t : (3, 3), (3,) array_like
        Pose of camera 2 relative to camera 1.

    Returns
    -------
    points3d : (N, 3) float64
        Points in the camera-1 frame; rows are NaN for points at infinity.
    """
    p1 = as_points2d(pts1, "pts1")
    p2 = as_points2d(pts2, "pts2")
    check_same_length(p1, p2)
    if len(p1) == 0:
        return np.zeros((0, 3))
    K = np.asarray(K, dtype=np.float64)
    P1 = projection_matrix(K, np.eye(3), np.zeros(3))
    P2 = projection_matrix(K, np.asarray(R, dtype=np.float64), np.asarray(t, dtype=np.float64))
    homog = cv2.triangulatePoints(P1, P2, p1.T, p2.T).T  # (N, 4)
    w = homog[:, 3:4]
    with np.errstate(divide="ignore", invalid="ignore"):
        points = homog[:, :3] / w
    points[np.abs(w[:, 0]) < 1e-12] = np.nan
    return points


def depths(points3d: FloatArray, R: FloatArray, t: FloatArray) -> tuple[FloatArray, FloatArray]:
    """Depths ``(N,)`` of camera-1-frame points in camera 1 and camera 2.

    Parameters
    ----------
    points3d : (N, 3) array_like
        Points in the camera-1 frame.
    R, t : (3, 3), (3,) array_like
        Relative pose ``x_cam2 = R x_cam1 + t``.

    Returns
    -------
    z1, z2 : (N,) float64 ndarray
    """
    z1 = points3d[:, 2]
    z2 = (points3d @ np.asarray(R).T + np.reshape(t, (1, 3)))[:, 2]
    return z1, z2


def reprojection_errors(
    points3d: FloatArray,
    pts1: FloatArray,
    pts2: FloatArray,
    K: FloatArray,
    R: FloatArray,
    t: FloatArray,
) -> FloatArray:
    """Per-point reprojection errors in pixels, ``(N, 2)``: column 0 image 1, column 1 image 2.

    Parameters
    ----------
    points3d : (N, 3) array_like
        Points in the camera-1 frame.
    pts1, pts2 : (N, 2) array_like
        Observed pixels in images 1 and 2.
    K : (3, 3) array_like
        Intrinsics shared by both views.
    R, t : (3, 3), (3,) array_like
        Relative pose ``x_cam2 = R x_cam1 + t``.

    Returns
    -------
    (N, 2) float64 ndarray
    """
    e1 = np.linalg.norm(project(points3d, K, np.eye(3), np.zeros(3)) - pts1, axis=1)
    e2 = np.linalg.norm(project(points3d, K, R, t) - pts2, axis=1)
    return np.column_stack([e1, e2])


def parallax_angles_deg(points3d: FloatArray, R: FloatArray, t: FloatArray) -> FloatArray:
    """Angle ``(N,)`` in degrees between the two viewing rays of each point.

    Camera 1 sits at the origin, camera 2 at ``C2 = -R^T t`` (camera-1 frame).

    Parameters
    ----------
    points3d : (N, 3) array_like
        Points in the camera-1 frame.
    R, t : (3, 3), (3,) array_like
        Relative pose ``x_cam2 = R x_cam1 + t``.

    Returns
    -------
    (N,) float64 ndarray
    """
    c2 = -np.asarray(R).T @ np.reshape(t, 3)
    ray1 = points3d
    ray2 = points3d - c2
    cos = np.sum(ray1 * ray2, axis=1) / (
        np.linalg.norm(ray1, axis=1) * np.linalg.norm(ray2, axis=1)
    )
    return np.degrees(np.arccos(np.clip(cos, -1.0, 1.0)))


def in_front_mask(points3d: FloatArray, R: FloatArray, t: FloatArray) -> np.ndarray:
    """``(N,) bool``: finite points with positive depth in both cameras (cheirality).

    Parameters
    ----------
    points3d : (N, 3) array_like
        Points in the camera-1 frame.
    R, t : (3, 3), (3,) array_like
        Relative pose ``x_cam2 = R x_cam1 + t``.

    Returns
    -------
    (N,) bool ndarray
    """
    finite = np.all(np.isfinite(points3d), axis=1)
    z1, z2 = depths(np.where(finite[:, None], points3d, 0.0), R, t)
    return finite & (z1 > 0) & (z2 > 0)


def behind_beyond_noise(points3d: FloatArray, R: FloatArray, t: FloatArray, K: ArrayLike,
                        noise_px: float) -> np.ndarray:
    """``(N,) bool``: matches whose point lies behind a camera by more than the noise explains.

    A correct match triangulates in front of both cameras (cheirality, H&Z section
    9.6.3), except a point so far away that its two rays are parallel within the
    noise: keypoint noise of ``noise_px`` per coordinate turns each ray by about
    ``noise_px / f`` radians, so the angle between them by ``sqrt(2)`` times that,
    and such a point may land on either side. A point behind a camera whose rays
    meet at more than three times that angle (the textbook 3-sigma bound) cannot be
    a correct match displaced by the noise: it is a wrong match that happens to lie
    near its epipolar line.

    Parameters
    ----------
    points3d : (N, 3) array
        Triangulated points in the camera-1 frame (NaN rows: at infinity, never
        flagged).
    R, t : (3, 3), (3,) array
        ``x_cam2 = R x_cam1 + t``.
    K : (3, 3) array_like
        Intrinsics shared by both views (its mean focal length converts the noise).
    noise_px : float
        Keypoint noise, per coordinate, in pixels.
    """
    K = np.asarray(K, dtype=np.float64)
    finite = np.all(np.isfinite(points3d), axis=1)
    safe = np.where(finite[:, None], points3d, 1.0)
    behind = finite & ~in_front_mask(safe, R, t)
    bound_deg = np.degrees(3.0 * np.sqrt(2.0) * noise_px / (0.5 * (K[0, 0] + K[1, 1])))
    return behind & (parallax_angles_deg(safe, R, t) > bound_deg)


#: :func:`behind_at_scene_parallax`: the least angle between the rays of a point behind a
#: camera, as a fraction of the median angle of the points in front, for it to count.
SCENE_PARALLAX_FRACTION = 0.25


def behind_at_scene_parallax(parallax_deg: FloatArray, behind: np.ndarray,
                             front: np.ndarray) -> np.ndarray:
    """``(N,) bool``: of the points ``behind`` a camera (:func:`behind_beyond_noise`), those
    whose rays meet at :data:`SCENE_PARALLAX_FRACTION` of the median angle of the points
    ``front`` of both cameras or more; ``parallax_deg`` ``(N,)`` are their angles
    (:func:`parallax_angles_deg`), ``behind`` and ``front`` ``(N,) bool``.

    A wrong match lies anywhere along its epipolar line, so its rays meet at angles
    like the scene's. A right match of a far point, which a focal length a few percent
    off or an uncorrected distortion pushes across infinity, lands behind at an angle
    far below the scene's (docs/benchmarks.md#inliers-behind-the-cameras): it is not a
    wrong match.

    Parameters
    ----------
    parallax_deg : (N,) ndarray
        Angle between each point's rays (deg).
    behind : (N,) bool ndarray
        Points behind a camera beyond the noise.
    front : (N,) bool ndarray
        Points in front of both cameras.

    Returns
    -------
    (N,) bool ndarray
    """
    if not front.any():
        return behind.copy()
    return behind & (parallax_deg >= SCENE_PARALLAX_FRACTION * median(parallax_deg[front]))
