"""The book's size rule, and halving by area averaging.

The book halves its 3072 px photos with ``cv2.pyrDown`` while they are wider than
1200 px. We keep the rule but halve by area averaging (each output pixel is the
mean of a ``2^L x 2^L`` block): for a JPEG file that is what the decoder's scaled
IDCT already produces (:func:`scene3D.io.images.load_working_image`), so the full-size
image is never decoded or held in memory. Pixel centres map as
``x' = (x + 0.5) / 2^L - 0.5`` (see :func:`scene3D.geometry.camera.scale_intrinsics_halved`).
"""

from __future__ import annotations

import cv2
import numpy as np

#: The book halves images while they are wider than this.
BOOK_MAX_WIDTH_PX = 1200


def halving_levels(width: int, max_width: int | None = BOOK_MAX_WIDTH_PX) -> int:
    """How many halvings bring ``width`` to at most ``max_width`` (the book's rule); None: 0.

    Parameters
    ----------
    width : int
        Image width (px).
    max_width : int or None, default BOOK_MAX_WIDTH_PX
        Largest working width (px); None for no limit.

    Returns
    -------
    int

    Raises
    ------
    ValueError
        If ``max_width`` is below 1.
    """
    if max_width is not None and max_width < 1:
        raise ValueError(f"max_width must be at least 1 px, got {max_width}")
    levels = 0
    while max_width is not None and width > max_width:
        width //= 2
        levels += 1
    return levels


def halve(img: np.ndarray, levels: int) -> np.ndarray:
    """Halve ``img`` ``levels`` times by area averaging: ``(H, W[, C]) -> (H >> L, W >> L[, C])``.

    Each output pixel is the mean of a ``2^L`` square block; rows and columns that
    do not fill a block (at the bottom and right) are dropped, so that the
    scaling is exact (:func:`scene3D.geometry.camera.scale_intrinsics_halved`).

    Parameters
    ----------
    img : (H, W) or (H, W, C) ndarray
        The image.
    levels : int
        Number of halvings ``L``.

    Returns
    -------
    (H >> L, W >> L) or (H >> L, W >> L, C) ndarray

    Raises
    ------
    ValueError
        If the image is too small to be halved that often.
    """
    if levels == 0:
        return img
    k = 1 << levels
    h, w = img.shape[0] // k, img.shape[1] // k
    if h == 0 or w == 0:
        raise ValueError(f"a {img.shape[1]}x{img.shape[0]} image cannot be halved {levels} times")
    return cv2.resize(img[:h * k, :w * k], (w, h), interpolation=cv2.INTER_AREA)
