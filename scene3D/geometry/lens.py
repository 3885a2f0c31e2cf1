"""Radial lens distortion: COLMAP's ``SIMPLE_RADIAL`` and ``RADIAL`` camera models.

A camera-frame point ``X`` with normalised coordinates ``n = (X / Z, Y / Z)`` is seen at

    pixel = c + f * n * (1 + k1 |n|^2 + k2 |n|^4)

(``k2 = 0`` for ``simple_radial``; ``pinhole`` has no coefficient). This is OpenCV's
model with ``dist = (k1, k2, 0, 0)`` and ``fx = fy = f``, and COLMAP's: barrel
distortion has ``k1 < 0``. The functions here map pixels between a distorting camera
and the pinhole camera ``K`` with the same ``f`` and ``c``, so that the pipeline's
two-view and many-view checks run in the undistorted geometry of the current estimate.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike

from .conventions import FloatArray

#: The camera models and how many radial coefficients each has.
CAMERA_MODELS: dict[str, int] = {"pinhole": 0, "simple_radial": 1, "radial": 2}

#: COLMAP's names for them (cameras.txt).
COLMAP_MODEL_NAMES: dict[str, str] = {"pinhole": "SIMPLE_PINHOLE",
                                      "simple_radial": "SIMPLE_RADIAL", "radial": "RADIAL"}


def radial_coefficients(camera_model: str) -> int:
    """How many radial coefficients ``camera_model`` has (0, 1 or 2).

    Parameters
    ----------
    camera_model : str
        A key of :data:`CAMERA_MODELS`.

    Returns
    -------
    int


    Raises
    ------
    ValueError
        ``camera_model`` is not one of :data:`CAMERA_MODELS`.
    """
    if camera_model not in CAMERA_MODELS:
        raise ValueError(f"unknown camera model {camera_model!r}: choose one of "
                         f"{', '.join(CAMERA_MODELS)}")
    return CAMERA_MODELS[camera_model]


def _padded(k: ArrayLike) -> tuple[float, float]:
    k = np.atleast_1d(np.asarray(k, np.float64))
    if k.size > 2:
        raise ValueError(f"at most two radial coefficients, got {k.size}")
    return (float(k[0]) if k.size > 0 else 0.0, float(k[1]) if k.size > 1 else 0.0)


def distort_normalized(n: ArrayLike, k: ArrayLike) -> FloatArray:
    """Distorted normalised coordinates ``n (1 + k1 |n|^2 + k2 |n|^4)``.

    Parameters
    ----------
    n : (N, 2) array_like
        Undistorted normalised coordinates ``(X / Z, Y / Z)``.
    k : (0,), (1,) or (2,) array_like
        Radial coefficients ``k1[, k2]``.

    Returns
    -------
    (N, 2) float64
    """
    n = np.asarray(n, np.float64).reshape(-1, 2)
    k1, k2 = _padded(k)
    r2 = np.sum(n * n, axis=1, keepdims=True)
    return n * (1.0 + k1 * r2 + k2 * r2 * r2)


def undistort_normalized(d: ArrayLike, k: ArrayLike, iterations: int = 30) -> FloatArray:
    """The inverse of :func:`distort_normalized`, by Newton's method on the radius.

    Parameters
    ----------
    d : (N, 2) array_like
        Distorted normalised coordinates.
    k : (0,), (1,) or (2,) array_like
    iterations : int
        Newton steps (the radius converges in 3-6 for the distortions of photos).

    Returns
    -------
    (N, 2) float64
        Undistorted coordinates. Beyond the radius where a barrel model folds over (its
        distorted radius stops growing) there is no inverse; those points keep the
        radius of the fold, the nearest the model can give.
    """
    d = np.asarray(d, np.float64).reshape(-1, 2)
    k1, k2 = _padded(k)
    if k1 == 0.0 and k2 == 0.0:
        return d.copy()
    rd = np.linalg.norm(d, axis=1)
    # The fold: d r_d / d r_u = 1 + 3 k1 r^2 + 5 k2 r^4 = 0 (a quadratic in r^2).
    roots = np.roots([5.0 * k2, 3.0 * k1, 1.0]) if k2 != 0.0 else (
        np.array([-1.0 / (3.0 * k1)]) if k1 != 0.0 else np.array([]))
    positive = [float(r.real) for r in np.atleast_1d(roots) if abs(r.imag) < 1e-12 and r.real > 0]
    r_fold = np.sqrt(min(positive)) if positive else np.inf
    ru = rd.copy()
    for _ in range(iterations):
        r2 = ru * ru
        value = ru * (1.0 + k1 * r2 + k2 * r2 * r2) - rd
        slope = 1.0 + 3.0 * k1 * r2 + 5.0 * k2 * r2 * r2
        ru = np.clip(ru - value / np.maximum(slope, 1e-6), 0.0, r_fold)
    scale = np.divide(ru, rd, out=np.ones_like(rd), where=rd > 0)
    return d * scale[:, None]


def _normalized(xy: ArrayLike, K: FloatArray) -> FloatArray:
    K = np.asarray(K, np.float64)
    return (np.asarray(xy, np.float64).reshape(-1, 2) - K[:2, 2]) / K[0, 0]


def undistort_pixels(xy: ArrayLike, K: ArrayLike, k: ArrayLike) -> FloatArray:
    """Pixels of a radially distorting camera as the pinhole camera ``K`` would see them.

    Parameters
    ----------
    xy : (N, 2) array_like
        Pixels of the distorting camera (OpenCV convention).
    K : (3, 3) array_like
        Its focal length ``K[0, 0]`` (square pixels, no skew) and principal point.
    k : (0,), (1,) or (2,) array_like
        Its radial coefficients.

    Returns
    -------
    (N, 2) float64
    """
    K = np.asarray(K, np.float64)
    return undistort_normalized(_normalized(xy, K), k) * K[0, 0] + K[:2, 2]


def distort_pixels(xy: ArrayLike, K: ArrayLike, k: ArrayLike) -> FloatArray:
    """The inverse of :func:`undistort_pixels`: pinhole pixels of ``K`` as the distorting
    camera sees them ``(N, 2)``.

    Parameters
    ----------
    xy : (N, 2) array_like
        Pinhole pixels of ``K`` (OpenCV convention).
    K : (3, 3) array_like
        Its focal length ``K[0, 0]`` (square pixels, no skew) and principal point.
    k : (0,), (1,) or (2,) array_like
        The distorting camera's radial coefficients.

    Returns
    -------
    (N, 2) float64 ndarray
    """
    K = np.asarray(K, np.float64)
    return distort_normalized(_normalized(xy, K), k) * K[0, 0] + K[:2, 2]


def rescaled_coefficients(k: ArrayLike, focal_from_px: float, focal_to_px: float) -> FloatArray:
    """The coefficients of the same lens when its normalised coordinates are measured with
    another focal length.

    Pixels undistorted with ``(focal_from_px, k)`` and then taken by a pinhole camera of
    focal length ``focal_to_px`` are an exact radial camera of focal length
    ``focal_to_px`` and coefficients ``k1 s^2, k2 s^4`` with ``s = focal_to_px /
    focal_from_px``.

    Parameters
    ----------
    k : (m,) array_like
        Radial coefficients about ``focal_from_px``.
    focal_from_px, focal_to_px : float
        Focal lengths (px) before and after.


    Returns
    -------
    (len(k),) float64
    """
    k = np.atleast_1d(np.asarray(k, np.float64))
    s2 = (focal_to_px / focal_from_px) ** 2
    return k * s2 ** np.arange(1, k.size + 1)


def corner_shifts_px(K: ArrayLike, k: ArrayLike, image_size: tuple[int, int]) -> FloatArray:
    """How the distortion ``k`` moves the image's four corners, in pixels ``(4, 2)``:
    where each is photographed minus where the pinhole camera ``K`` would see it.

    Parameters
    ----------
    K : (3, 3) array_like
    k : array_like
    image_size : (width, height)
    """
    w, h = image_size
    corners = np.array([[0.0, 0.0], [w - 1.0, 0.0], [0.0, h - 1.0], [w - 1.0, h - 1.0]])
    K = np.asarray(K, np.float64)
    return corners - undistort_pixels(corners, K, k)


def folds_within(K: ArrayLike, k: ArrayLike, image_size: tuple[int, int]) -> bool:
    """Whether the lens ``k`` folds over inside the image: a barrel lens whose distorted
    radius stops growing (``1 + 3 k1 r^2 + 5 k2 r^4 <= 0``) before the farthest corner,
    so that the model maps two points to one pixel there and cannot be undistorted.

    Parameters
    ----------
    K : (3, 3) array_like
    k : array_like
    image_size : (width, height)
    """
    k1, k2 = _padded(k)
    w, h = image_size
    K = np.asarray(K, np.float64)
    corners = np.array([[0.0, 0.0], [w - 1.0, 0.0], [0.0, h - 1.0], [w - 1.0, h - 1.0]])
    r_d = float(np.max(np.linalg.norm(_normalized(corners, K), axis=1)))
    radii = np.linspace(0.0, 3.0 * r_d, 601)  # r_u out to where r_d(r_u) passes the corner
    slope = 1.0 + 3.0 * k1 * radii**2 + 5.0 * k2 * radii**4
    reach = radii * (1.0 + k1 * radii**2 + k2 * radii**4)
    inside = np.flatnonzero(reach >= r_d)
    last = inside[0] if inside.size else len(radii)
    return bool(np.any(slope[:last] <= 0))


def max_shift_px(K: ArrayLike, k: ArrayLike, image_size: tuple[int, int]) -> float:
    """How far the distortion ``k`` moves the image's farthest corner, in pixels
    (:func:`corner_shifts_px`).

    Parameters
    ----------
    K : (3, 3) array_like
        Focal length ``K[0, 0]`` (square pixels, no skew) and principal point.
    k : (0,), (1,) or (2,) array_like
        Radial coefficients.
    image_size : (int, int)
        ``(width, height)`` of the images in px.

    Returns
    -------
    float
    """
    return float(np.max(np.linalg.norm(corner_shifts_px(K, k, image_size), axis=1)))
