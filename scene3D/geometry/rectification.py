"""Stereo rectification of a calibrated pair with known relative pose."""

from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np

from .conventions import FloatArray, image_size


@dataclass(frozen=True)
class RectifiedPair:
    """Two images warped so that corresponding points share a row (a column, when the
    baseline is mostly vertical: :func:`baseline_axis`).

    Attributes
    ----------
    img1, img2 : (H, W, 3) uint8
        Rectified images, same size as the inputs.
    R1, R2 : (3, 3) float64
        Rotations from each camera frame to its rectified frame: ``R_rect1_from_cam1``
        and ``R_rect2_from_cam2`` (``x_rect = R1 x_cam1``).
    P1, P2 : (3, 4) float64
        Projection matrices of the rectified cameras (in the rectified camera-1
        frame); ``P2[0, 3] = -f * baseline`` (``P2[1, 3]`` for a vertical one).
    Q : (4, 4) float64
        Disparity-to-depth matrix for ``cv2.reprojectImageTo3D``, for disparities
        between these two images.
    """

    img1: np.ndarray
    img2: np.ndarray
    R1: FloatArray
    R2: FloatArray
    P1: FloatArray
    P2: FloatArray
    Q: FloatArray


def rectifying_transforms(
    K: FloatArray, R: FloatArray, t: FloatArray, size: tuple[int, int], alpha: float = 1.0,
) -> tuple[FloatArray, FloatArray, FloatArray, FloatArray, FloatArray]:
    """``R1, R2, P1, P2, Q`` of ``cv2.stereoRectify`` with zero disparity at infinity
    (both rectified cameras share ``f`` and the principal point); ``size`` is (W, H).

    Parameters
    ----------
    K : (3, 3) array_like
        Intrinsics shared by both (undistorted) images.
    R, t : (3, 3), (3,) array_like
        Relative pose ``x_cam2 = R x_cam1 + t``.
    size : (int, int)
        ``(width, height)`` in px.
    alpha : float, default 1.0
        ``cv2.stereoRectify``'s free scaling (0: valid pixels only, 1: all pixels kept).

    Returns
    -------
    R1, R2 : (3, 3) float64 ndarray
        Rectifying rotations of cameras 1 and 2.
    P1, P2 : (3, 4) float64 ndarray
        Projection matrices of the rectified cameras.
    Q : (4, 4) float64 ndarray
        Disparity-to-depth matrix.
    """
    no_dist = np.zeros(5)
    R1, R2, P1, P2, Q, _, _ = cv2.stereoRectify(
        K, no_dist, K, no_dist, size, np.asarray(R, np.float64),
        np.asarray(t, np.float64).reshape(3, 1), flags=cv2.CALIB_ZERO_DISPARITY, alpha=alpha,
    )
    return R1, R2, P1, P2, Q


def baseline_axis(P2: FloatArray) -> int:
    """0 when rectified image 2 lies beside image 1 (rows correspond, disparities along
    x), 1 when OpenCV rectified a mostly vertical baseline (columns correspond,
    disparities along y); read off ``P2``'s translation column.

    Parameters
    ----------
    P2 : (3, 4) array_like
        Rectified projection matrix of camera 2.

    Returns
    -------
    int
    """
    return int(abs(P2[1, 3]) > abs(P2[0, 3]))


def rectify_pair(
    img1: np.ndarray,
    img2: np.ndarray,
    K: FloatArray,
    R: FloatArray,
    t: FloatArray,
    alpha: float = 1.0,
    shift2_px: float = 0.0,
) -> RectifiedPair:
    """Rectify two undistorted images with ``cv2.stereoRectify``.

    Parameters
    ----------
    img1, img2 : (H, W, C) uint8
        Undistorted images of the same size.
    K : (3, 3)
        Intrinsics of both images.
    R, t : (3, 3), (3,)
        ``x_cam2 = R x_cam1 + t``.
    alpha : float
        0 crops to valid pixels only, 1 keeps every source pixel (the book's choice).
    shift2_px : float
        Moves rectified image 2's principal point this far along the baseline (x, or y
        where OpenCV rectifies a mostly vertical baseline by columns:
        :func:`baseline_axis`), so that a point of disparity ``d`` (zero at infinity)
        has ``d - shift2_px`` between the two rectified images. A converging pair's
        disparities can exceed the image width, putting image 2's view of what image 1
        sees beyond its edge; the shift brings it back. ``P2`` and ``Q`` include it.
    """
    size = image_size(img1)  # (width, height): the book passed (height, width)
    R1, R2, P1, P2, Q = rectifying_transforms(K, R, t, size, alpha)
    if shift2_px:
        axis = baseline_axis(P2)
        P2 = P2.copy()
        P2[axis, 2] += shift2_px
        Q = Q.copy()
        # (c1 - c2) / T along the baseline, T = P2[axis, 3] / f: OpenCV's last entry.
        Q[3, 3] = (P1[axis, 2] - P2[axis, 2]) / P2[axis, 3] * P2[axis, axis]
    no_dist = np.zeros(5)
    map1x, map1y = cv2.initUndistortRectifyMap(K, no_dist, R1, P1, size, cv2.CV_32FC1)
    map2x, map2y = cv2.initUndistortRectifyMap(K, no_dist, R2, P2, size, cv2.CV_32FC1)
    rect1 = cv2.remap(img1, map1x, map1y, cv2.INTER_LINEAR)
    rect2 = cv2.remap(img2, map2x, map2y, cv2.INTER_LINEAR)
    return RectifiedPair(rect1, rect2, R1, R2, P1, P2, Q)


def rectify_points(
    points: FloatArray, K: FloatArray, R_rect: FloatArray, P_rect: FloatArray
) -> FloatArray:
    """Map pixels ``(N, 2)`` of an undistorted image to its rectified image.

    Parameters
    ----------
    points : (N, 2) ndarray
        Pixels of the undistorted image.
    K : (3, 3) array_like
        Its intrinsics.
    R_rect : (3, 3) array_like
        Its rectifying rotation, ``R_rect_from_cam`` (:attr:`RectifiedPair.R1` or ``R2``).
    P_rect : (3, 4) array_like
        Its rectified projection matrix.

    Returns
    -------
    (N, 2) float64 ndarray
    """
    if len(points) == 0:
        return np.zeros((0, 2))
    out = cv2.undistortPoints(points.reshape(-1, 1, 2), K, None, R=R_rect, P=P_rect)
    return out.reshape(-1, 2).astype(np.float64)
