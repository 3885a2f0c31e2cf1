"""Reading images from paths or arrays into BGR ``uint8``, and the book's pyramid rule."""

from __future__ import annotations

import logging
import os
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path

import cv2
import numpy as np

from .camera import has_distortion, undistort_image

logger = logging.getLogger(__name__)

ImageSource = str | os.PathLike | np.ndarray

#: File endings taken as images when a folder is given.
IMAGE_SUFFIXES = frozenset({".jpg", ".jpeg", ".png", ".bmp", ".tif", ".tiff", ".webp", ".pgm",
                            ".ppm"})

#: The book halves images with ``cv2.pyrDown`` while they are wider than this.
BOOK_MAX_WIDTH_PX = 1200


def read_image(path: str | os.PathLike) -> np.ndarray:
    """Read an image file as stored: grey or colour, 8 or 16 bits (an alpha channel is dropped).

    The pixels are taken as stored: EXIF orientation is not applied, so that
    they match the sensor layout a calibration describes.

    Raises
    ------
    FileNotFoundError
        If ``path`` does not exist.
    ValueError
        If the file is empty or not an image OpenCV can decode.
    """
    path = Path(path)
    if not path.is_file():
        raise FileNotFoundError(f"image not found: '{path}'")
    data = np.fromfile(path, dtype=np.uint8)  # works with non-ASCII paths too
    if data.size == 0:
        raise ValueError(f"cannot read image '{path}': the file is empty")
    # Any depth (16-bit stays 16-bit) and grey or colour as stored; alpha is dropped.
    flags = cv2.IMREAD_ANYDEPTH | cv2.IMREAD_ANYCOLOR | cv2.IMREAD_IGNORE_ORIENTATION
    img = cv2.imdecode(data, flags)
    if img is None:
        raise ValueError(f"cannot read image '{path}': not an image file")
    return img


def to_bgr8(img: np.ndarray, name: str = "image") -> np.ndarray:
    """Convert grey, BGR or BGRA images of ``uint8``/``uint16`` depth to BGR ``uint8``.

    16-bit images are scaled by 1/257 (full range to full range).

    Raises
    ------
    ValueError
        For other dtypes or channel counts, or an empty image.
    """
    if not isinstance(img, np.ndarray):
        raise ValueError(f"`{name}` must be a path or a numpy array, got {type(img).__name__}")
    if img.size == 0 or img.ndim not in (2, 3):
        raise ValueError(f"`{name}` must be an (H, W) or (H, W, C) image, got shape {img.shape}")
    if img.dtype == np.uint16:
        img = (img.astype(np.float32) / 257.0 + 0.5).astype(np.uint8)
    elif img.dtype != np.uint8:
        raise ValueError(f"`{name}` must be uint8 or uint16, got {img.dtype}")
    if img.ndim == 2 or img.shape[2] == 1:
        return cv2.cvtColor(img.reshape(img.shape[:2]), cv2.COLOR_GRAY2BGR)
    if img.shape[2] == 3:
        return np.ascontiguousarray(img)
    if img.shape[2] == 4:
        return cv2.cvtColor(img, cv2.COLOR_BGRA2BGR)
    raise ValueError(f"`{name}` must have 1, 3 or 4 channels, got {img.shape[2]}")


def load_bgr(source: ImageSource, name: str = "image") -> np.ndarray:
    """Load a path or take an array, and return it as BGR ``uint8`` ``(H, W, 3)``."""
    if isinstance(source, (str, os.PathLike)):
        return to_bgr8(read_image(source), name=str(source))
    return to_bgr8(source, name=name)


def load_bgr_pair(
    source1: ImageSource, source2: ImageSource
) -> tuple[np.ndarray, np.ndarray]:
    """:func:`load_bgr` of two images at once (decoding releases the GIL)."""
    with ThreadPoolExecutor(max_workers=2) as pool:
        first = pool.submit(load_bgr, source1, "img1")
        second = pool.submit(load_bgr, source2, "img2")
        return first.result(), second.result()


def working_image(img: np.ndarray, K: np.ndarray, dist: np.ndarray, levels: int) -> np.ndarray:
    """Undistort at native resolution (where the model holds), then ``pyrDown`` ``levels`` times."""
    if has_distortion(dist):
        img = undistort_image(img, K, dist)
    return pyr_down(img, levels)


def pyr_down_levels(width: int, max_width: int = BOOK_MAX_WIDTH_PX) -> int:
    """How many ``pyrDown`` halvings bring ``width`` to at most ``max_width`` (the book's rule)."""
    levels = 0
    while width > max_width:
        width = (width + 1) // 2
        levels += 1
    return levels


def pyr_down(img: np.ndarray, levels: int) -> np.ndarray:
    """Apply ``cv2.pyrDown`` ``levels`` times."""
    for _ in range(levels):
        img = cv2.pyrDown(img)
    return img


def image_size(img: np.ndarray) -> tuple[int, int]:
    """Return (width, height) of an image array."""
    return int(img.shape[1]), int(img.shape[0])
