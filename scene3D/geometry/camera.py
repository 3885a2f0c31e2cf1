"""Camera intrinsics: validation, rescaling to another image size, undistortion.

See :mod:`scene3D.geometry` for the pixel convention (integer coordinates at
pixel centres).
"""

from __future__ import annotations

import os

import cv2
import numpy as np
from numpy.typing import ArrayLike

from .conventions import FloatArray

VALID_DIST_LENGTHS = (0, 4, 5, 8, 12, 14)
#: OpenCV's distortion coefficients in their order (a vector holds the first 4-14).
DISTORTION_NAMES = ("k1", "k2", "p1", "p2", "k3", "k4", "k5", "k6", "s1", "s2", "s3", "s4",
                    "tx", "ty")

#: The focal lengths :func:`check_intrinsics_for_size` takes, as multiples of the image's
#: longer side: from a fisheye's (about 0.3) to a 2000 mm lens on a 36 mm sensor (about 55).
FOCAL_RANGE_OF_SIDE = (0.05, 100.0)

#: The largest ratio of ``fy`` to ``fx`` (or back) that :func:`check_intrinsics_for_size`
#: takes: pixels are square on almost every camera; anamorphic formats stretch by up to 2.
MAX_PIXEL_ASPECT = 4.0

#: The largest skew ``K[0, 1]`` that :func:`validate_intrinsics` takes, as a fraction of
#: ``fx``: pixel axes about 84 degrees apart. Real cameras have none; a larger value is a
#: mistyped matrix, not a camera.
MAX_SKEW_OF_FOCAL = 0.1


def validate_intrinsics(K: ArrayLike) -> FloatArray:
    """Return ``K`` as a ``(3, 3) float64`` camera matrix after checking it.

    Parameters
    ----------
    K : (3, 3) array_like
        Camera matrix ``[[fx, s, cx], [0, fy, cy], [0, 0, 1]]`` in pixels.

    Returns
    -------
    (3, 3) float64 ndarray


    Raises
    ------
    TypeError
        If ``K`` is None or a path.
    ValueError
        If ``K`` is not 3x3 and finite, its focal lengths are not positive or its
        last row is not ``[0, 0, 1]``.
    """
    if K is None or isinstance(K, (str, bytes, os.PathLike)):
        raise TypeError(f"`K` must be a 3x3 camera matrix, got {K!r} (a calibration file "
                        "is read by scene3D.io.calibration.load_calibration)")
    if np.iscomplexobj(K):
        raise ValueError("`K` must be real, got complex values")
    arr = np.asarray(K, dtype=np.float64)
    if arr.shape != (3, 3):
        raise ValueError(f"`K` must have shape (3, 3), got {arr.shape}")
    if not np.all(np.isfinite(arr)):
        raise ValueError("`K` contains non-finite values")
    if arr[0, 0] <= 0 or arr[1, 1] <= 0:
        raise ValueError(
            f"`K` must have positive focal lengths, got fx={arr[0, 0]:g}, fy={arr[1, 1]:g}"
        )
    if not np.allclose(arr[2], [0.0, 0.0, 1.0]) or arr[1, 0] != 0:
        raise ValueError(
            f"`K` must be upper triangular with last row [0, 0, 1], got {arr.tolist()}"
        )
    if abs(arr[0, 1]) > MAX_SKEW_OF_FOCAL * arr[0, 0]:
        raise ValueError(f"`K` has a skew of {arr[0, 1]:g} px against fx={arr[0, 0]:g}: no "
                         "camera's pixel axes are that far from square (it is 0 for almost all)")
    return arr


def check_intrinsics_for_size(K: FloatArray, image_size: tuple[int, int]) -> None:
    """Raise ``ValueError`` when ``K`` cannot be a camera's for images of ``image_size``
    (width, height): a principal point more than half the image beyond its edges (it lies
    near the centre; a crop moves it, but within the image the calibration holds for), a
    focal length outside :data:`FOCAL_RANGE_OF_SIDE` times the longer side, or pixels
    more than :data:`MAX_PIXEL_ASPECT` times longer one way than the other.

    Parameters
    ----------
    K : (3, 3) float64 ndarray
        Intrinsics (pixels, OpenCV convention).
    image_size : (int, int)
        ``(width, height)`` of the images in px.

    Raises
    ------
    ValueError
        If ``K`` cannot be a camera's for that size.
    """
    w, h = image_size
    cx, cy = K[0, 2], K[1, 2]
    if not (-0.5 * w <= cx <= 1.5 * w and -0.5 * h <= cy <= 1.5 * h):
        raise ValueError(f"the principal point ({cx:g}, {cy:g}) lies far outside the "
                         f"{w}x{h} image (it is near the centre for a real camera)")
    low, high = (bound * max(w, h) for bound in FOCAL_RANGE_OF_SIDE)
    for name, f in (("fx", K[0, 0]), ("fy", K[1, 1])):
        if not low <= f <= high:
            raise ValueError(f"the focal length {name}={f:g} px is not a camera's for a {w}x{h} "
                             f"image (between {low:g} and {high:g} px: a fisheye to a long "
                             "telephoto)")
    if not 1 / MAX_PIXEL_ASPECT <= K[1, 1] / K[0, 0] <= MAX_PIXEL_ASPECT:
        raise ValueError(f"fx={K[0, 0]:g} and fy={K[1, 1]:g} px differ more than a camera's "
                         "do (they are equal for square pixels)")


def larger_photos_factor(K: FloatArray, image_size: tuple[int, int]) -> float | None:
    """How many times larger the photos ``K`` seems made for are than ``image_size``
    (width, height), or None: its principal point lies where a ``K`` for larger photos
    puts it, as far beyond the centre in x as in y (at least 1.5 times the centre's
    coordinates, the two within 15 % of each other), rounded to a half when near one.

    Parameters
    ----------
    K : (3, 3) float64 ndarray
        Intrinsics (pixels, OpenCV convention).
    image_size : (int, int)
        ``(width, height)`` of the images in px.

    Returns
    -------
    float or None
    """
    w, h = image_size
    ratios = np.array([K[0, 2] / (w / 2), K[1, 2] / (h / 2)])
    if not (ratios.min() > 1.5 and ratios.max() < 1.15 * ratios.min()):
        return None
    s = float(ratios.mean())
    nice = round(2 * s) / 2  # photos are mostly scaled by whole or half factors
    return nice if abs(nice - s) < 0.05 * s else round(s, 1)


def larger_photos_hint(K: FloatArray, image_size: tuple[int, int]) -> str:
    """A question naming the factor of :func:`larger_photos_factor` and how to rescale
    ``K``, or '' when its principal point does not suggest larger photos.

    Parameters
    ----------
    K : (3, 3) float64 ndarray
        Intrinsics (pixels, OpenCV convention).
    image_size : (int, int)
        ``(width, height)`` of the images in px.

    Returns
    -------
    str
    """
    s = larger_photos_factor(K, image_size)
    if s is None:
        return ""
    w, h = image_size
    return (f"a K for photos about {s:g} times larger (about {w * s:.0f}x{h * s:.0f})? "
            f"scene3D.geometry.camera.scale_intrinsics(K, {w} / W, {h} / H), W x H the size it was "
            "calibrated at, fits it to these")


#: How far from the image centre a principal point may lie, as a share of the image's
#: width (in x) and height (in y), before a pose found with it is flagged: calibrated
#: cameras put it within a few per cent of the centre; a crop moves it.
MAX_PRINCIPAL_OFFSET_OF_SIDE = 0.2


def principal_point_hint(K: FloatArray, image_size: tuple[int, int]) -> str:
    """Why ``K``'s principal point is implausible for images of ``image_size`` (width,
    height), as a question with a hint, or '': when it lies where a ``K`` for larger
    photos puts it (:func:`larger_photos_hint`), where one for the photos turned by 90
    degrees does, or otherwise more than :data:`MAX_PRINCIPAL_OFFSET_OF_SIDE` of a side
    from the centre.

    Parameters
    ----------
    K : (3, 3) float64 ndarray
        Intrinsics (pixels, OpenCV convention).
    image_size : (int, int)
        ``(width, height)`` of the images in px.

    Returns
    -------
    str
    """
    w, h = image_size
    cx, cy = float(K[0, 2]), float(K[1, 2])
    offsets = np.abs([cx - (w - 1) / 2, cy - (h - 1) / 2]) / np.array([w, h])
    if np.all(offsets <= MAX_PRINCIPAL_OFFSET_OF_SIDE):
        return ""
    where = (f"K's principal point ({round(cx):d}, {round(cy):d}) lies far from the centre "
             f"of the {w}x{h} images")
    if hint := larger_photos_hint(K, image_size):
        return f"{where}: {hint}"
    turned = np.abs([cx - (h - 1) / 2, cy - (w - 1) / 2]) / np.array([h, w])
    if w != h and np.all(turned <= MAX_PRINCIPAL_OFFSET_OF_SIDE):
        return (f"{where}, and near that of {h}x{w} ones: a K for the photos turned by 90 "
                "degrees? (photos stored upright, or read with their EXIF orientation "
                "applied, need K with x and y swapped)")
    return (f"{where} (a calibrated camera's lies within a few per cent of it; a crop moves "
            "it): is K for these photos?")


def check_intrinsics_for_native_size(K: FloatArray, image_size: tuple[int, int],
                                     what: str = "`K`") -> None:
    """:func:`check_intrinsics_for_size` for a ``K`` given with images (the library's
    ``K`` is for their native, stored size): the ``ValueError`` says so, and when the
    principal point sits where a ``K`` for larger photos puts it, by how much to scale
    it (:func:`larger_photos_hint`).

    Parameters
    ----------
    K : (3, 3) float64 ndarray
        Intrinsics for the images' native (stored) size.
    image_size : (int, int)
        ``(width, height)`` of the images in px.
    what : str, default "`K`"
        How the message names ``K``.

    Raises
    ------
    ValueError
        If ``K`` cannot be a camera's for that size.
    """
    try:
        check_intrinsics_for_size(K, image_size)
    except ValueError as exc:
        w, h = image_size
        message = (f"{what} does not fit images of {w}x{h} px, their native size, which it "
                   f"must be for: {exc}")
        hint = larger_photos_hint(K, image_size)
        raise ValueError(message + (f"; {hint}" if hint else "")) from None


def validate_distortion(dist: ArrayLike | None) -> FloatArray:
    """Return OpenCV distortion coefficients as a flat ``(n,) float64`` array.

    ``None`` means no distortion. Valid lengths are 0, 4, 5, 8, 12 and 14.

    Parameters
    ----------
    dist : array_like or None
        OpenCV distortion coefficients ``(k1, k2, p1, p2[, k3[, ...]])``; None for none.

    Returns
    -------
    (n,) float64 ndarray

    Raises
    ------
    ValueError
        For another length, or non-finite values.
    """
    if dist is None:
        return np.zeros(0)
    arr = np.asarray(dist, dtype=np.float64).ravel()
    if arr.size not in VALID_DIST_LENGTHS:
        raise ValueError(
            f"`dist` must have 0, 4, 5, 8, 12 or 14 coefficients, got {arr.size}"
        )
    if not np.all(np.isfinite(arr)):
        raise ValueError("`dist` contains non-finite values")
    return arr


def has_distortion(dist: FloatArray) -> bool:
    """True when any distortion coefficient is non-zero.

    Parameters
    ----------
    dist : (n,) ndarray
        OpenCV distortion coefficients.

    Returns
    -------
    bool
    """
    return bool(np.any(dist != 0))


def scale_intrinsics(K: FloatArray, sx: float, sy: float) -> FloatArray:
    """Intrinsics of an image scaled by ``(sx, sy)`` with pixel edges kept on pixel edges.

    With pixel centres at integer coordinates, ``x' = sx (x + 0.5) - 0.5``: what
    ``cv2.resize`` and area averaging (and JPEG's scaled decoding) do.

    Parameters
    ----------
    K : (3, 3) array_like
        Intrinsics of the original image (pixels, OpenCV convention).
    sx, sy : float
        Scale factors along x (width) and y (height).

    Returns
    -------
    (3, 3) float64 ndarray
    """
    K2 = np.array(K, dtype=np.float64)
    K2[0, :2] *= sx
    K2[1, 1] *= sy
    K2[0, 2] = sx * (K[0, 2] + 0.5) - 0.5
    K2[1, 2] = sy * (K[1, 2] + 0.5) - 0.5
    return K2


def with_focal(K: ArrayLike, focal_px: float) -> FloatArray:
    """``K`` ``(3, 3)`` with both focal lengths set to ``focal_px`` (principal point kept).

    Parameters
    ----------
    K : (3, 3) array_like
        Intrinsics.
    focal_px : float
        Focal length (px) for both ``fx`` and ``fy``.

    Returns
    -------
    (3, 3) float64 ndarray
    """
    K = np.array(K, dtype=np.float64)
    K[0, 0] = K[1, 1] = focal_px
    return K


def scale_intrinsics_halved(K: FloatArray, levels: int) -> FloatArray:
    """Intrinsics after halving the image ``levels`` times by area averaging.

    See :func:`scene3D.io.images.halve`: one output pixel averages a
    ``2^levels`` square of input pixels.

    Parameters
    ----------
    K : (3, 3) array_like
        Intrinsics of the full-size image.
    levels : int
        Number of halvings.

    Returns
    -------
    (3, 3) float64 ndarray
    """
    s = 0.5**levels
    return scale_intrinsics(K, s, s)


def scale_intrinsics_resize(
    K: FloatArray, from_size: tuple[int, int], to_size: tuple[int, int]
) -> FloatArray:
    """Intrinsics of an image resized from ``from_size`` to ``to_size`` (width, height).

    Parameters
    ----------
    K : (3, 3) array_like
        Intrinsics at ``from_size``.
    from_size, to_size : (int, int)
        ``(width, height)`` in px.

    Returns
    -------
    (3, 3) float64 ndarray
    """
    return scale_intrinsics(K, to_size[0] / from_size[0], to_size[1] / from_size[1])


def _same_aspect(image_size: tuple[int, int], calib_size: tuple[int, int],
                 tolerance: float) -> bool:
    """Whether images of ``image_size`` have the aspect ratio of ``calib_size`` (width,
    height) within ``tolerance``, relative."""
    (w, h), (cw, ch) = image_size, calib_size
    return abs(cw * h / (ch * w) - 1.0) <= tolerance


def different_sizes_message(name: str, size: tuple[int, int], first_name: str,
                            first_size: tuple[int, int]) -> str:
    """The one-line error for photo ``name`` of ``size`` next to ``first_name`` of
    ``first_size`` (width, height): one camera matrix holds for one size, whether it comes
    from a calibration or from the photos. Says what to do: store a rotated photo the
    same way round, give a resized one (the same aspect ratio) the other's size, replace
    a cropped one by the camera's original.

    Parameters
    ----------
    name : str
        The photo whose size differs.
    size : (int, int)
        Its ``(width, height)`` in px.
    first_name : str
        The photo it is compared with.
    first_size : (int, int)
        Its ``(width, height)`` in px.

    Returns
    -------
    str
    """
    (w, h), (w0, h0) = size, first_size
    head = f"'{name}' is {w}x{h} but '{first_name}' is {w0}x{h0}"
    if (w, h) == (h0, w0):
        return f"{head}: one was rotated; store both the same way round"
    head += ": photos of one camera at one size are needed"
    if _same_aspect(first_size, size, 0.01):
        small = min((w, h), (w0, h0))
        return (f"{head}; one was resized: use the camera's originals, or resize the larger "
                f"to {small[0]}x{small[1]}")
    return f"{head}; one was cropped, or taken with another camera: use the camera's originals"


def adapt_intrinsics_to_size(
    K: FloatArray,
    calib_size: tuple[int, int],
    image_size: tuple[int, int],
    aspect_tolerance: float = 0.01,
    what: str = "the calibration",
) -> FloatArray:
    """Return ``K`` for images of ``image_size`` when it was calibrated at ``calib_size``.

    Sizes are (width, height). Same size: ``K`` unchanged. Same aspect ratio
    (within ``aspect_tolerance``, relative): ``K`` scaled. Otherwise the
    calibration does not describe these images; the error names ``what`` gave ``K``
    and says whether the images are turned by 90 degrees from it.

    Parameters
    ----------
    K : (3, 3) float64 ndarray
        Intrinsics at ``calib_size``.
    calib_size, image_size : (int, int)
        ``(width, height)`` in px of the calibration and of the images.
    aspect_tolerance : float, default 0.01
        Relative tolerance on the aspect ratios.
    what : str, default "the calibration"
        How the message names where ``K`` came from.

    Returns
    -------
    (3, 3) float64 ndarray


    Raises
    ------
    ValueError
        If the aspect ratios differ.
    """
    if tuple(calib_size) == tuple(image_size):
        return K.copy()
    (w, h), (cw, ch) = image_size, calib_size
    if not _same_aspect(image_size, calib_size, aspect_tolerance):
        head = f"images are {w}x{h} but {what} is for {cw}x{ch}"
        if _same_aspect((h, w), calib_size, aspect_tolerance):
            def shape(width: int, height: int) -> str:
                return "portrait" if height > width else "landscape"
            raise ValueError(f"{head}: the images are turned by 90 degrees from it "
                             f"({shape(w, h)} against {shape(cw, ch)}); turn them back to "
                             f"{shape(cw, ch)} (scene3D uses the pixels as stored, not the EXIF "
                             "orientation)")
        raise ValueError(f"{head}, another aspect ratio: cropped images, or another camera's? "
                         "It holds for images of its size and copies scaled from them")
    return scale_intrinsics_resize(K, calib_size, image_size)


def undistort_image(img: np.ndarray, K: FloatArray, dist: FloatArray) -> np.ndarray:
    """Remove lens distortion, keeping ``K`` as the camera matrix of the result.

    Parameters
    ----------
    img : (H, W) or (H, W, C) ndarray
        The image as read (any dtype ``cv2.undistort`` takes), pixels ``img[y, x]``.
    K : (3, 3) float64
        Intrinsics of ``img``'s size (pixels, OpenCV convention).
    dist : (k,) float64
        OpenCV distortion coefficients (:func:`validate_distortion`).

    Returns
    -------
    ndarray
        The same shape and dtype as ``img``, as a pinhole camera with ``K`` would see it
        (pixels mapped from outside the image are black); ``img`` itself when ``dist``
        is all zeros.
    """
    if not has_distortion(dist):
        return img
    return cv2.undistort(img, K, dist, None, K)
