"""A small copy of each depth map, kept after fusion for the report's thumbnails.

Fusion needs every view's full depth map at once; once the cloud is fused, only a preview of
each is kept (about 160 pixels wide), so that the maps of many views are not held while the
mesh is made and the report written.
"""

from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np

#: The previews' width in pixels.
PREVIEW_WIDTH = 160


@dataclass(frozen=True)
class DepthPreview:
    """One view's depth map, shrunk.

    Attributes
    ----------
    depth : (h, w) float32
        Camera ``z``, the mean of the depths of each preview pixel's footprint; NaN where
        fewer than half of those pixels have one.
    image_size : (int, int)
        ``(width, height)`` of the full depth map.
    valid_pixels : int
        Pixels of the full map with a depth.
    """

    depth: np.ndarray
    image_size: tuple[int, int]
    valid_pixels: int


def depth_preview(depth: np.ndarray, width: int = PREVIEW_WIDTH) -> DepthPreview:
    """The preview of a depth map ``(H, W)`` (NaN where there is no depth).

    Parameters
    ----------
    depth : (H, W) array_like
        Camera ``z``.
    width : int, default PREVIEW_WIDTH
        The preview's width (not wider than the map).

    Returns
    -------
    DepthPreview
    """
    depth = np.asarray(depth, dtype=np.float32)
    if depth.ndim != 2:
        raise ValueError(f"`depth` must have shape (H, W), got {depth.shape}")
    h, w = depth.shape
    valid = np.isfinite(depth)
    size = (min(width, w), max(1, round(h * min(width, w) / w)))
    # Area averages of the depths and of the mask: a pixel's mean depth over its footprint's
    # valid pixels, so that holes neither pull depths to zero nor spread NaN.
    cover = cv2.resize(valid.astype(np.float32), size, interpolation=cv2.INTER_AREA)
    total = cv2.resize(np.where(valid, depth, 0).astype(np.float32), size,
                       interpolation=cv2.INTER_AREA)
    with np.errstate(invalid="ignore", divide="ignore"):
        small = np.where(cover >= 0.5, total / cover, np.nan).astype(np.float32)
    return DepthPreview(small, (w, h), int(np.count_nonzero(valid)))
