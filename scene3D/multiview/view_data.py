"""The data of the views and their pairs: one working image's keypoints
(:class:`ViewFeatures`) and one pair's verified matches (:class:`PairMatches`).

Pixels are those of the working images (OpenCV convention).
"""

from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np

from ..geometry.conventions import FloatArray


@dataclass(frozen=True)
class ViewFeatures:
    """Keypoints of one working image.

    Attributes
    ----------
    keypoints : (N, 2) float64
        Pixels.
    descriptors : (N, D)
        float32 (SIFT) or uint8 (binary descriptors).
    colors : (N, 3) uint8
        RGB at each keypoint.
    norm : int
        The descriptor distance, ``cv2.NORM_L2`` or ``cv2.NORM_HAMMING``.
    words : (N, p) int16 or None
        The ``p`` visual words nearest to each descriptor, nearest first
        (:mod:`scene3D.multiview.retrieval`); set once the collection's vocabulary is
        known, None before.
    sizes : (N,) float64 or None
        Keypoint sizes in pixels (``cv2.KeyPoint.size``); None when unknown (every
        keypoint is then taken as equally precise).
    """

    keypoints: FloatArray
    descriptors: np.ndarray
    colors: np.ndarray
    norm: int = cv2.NORM_L2
    words: np.ndarray | None = None
    sizes: FloatArray | None = None


@dataclass(frozen=True)
class PairMatches:
    """Verified matches of views ``i < j``: keypoint ``idx_i[k]`` of ``i`` is ``idx_j[k]`` of ``j``.

    Attributes
    ----------
    i, j : int
    idx_i, idx_j : (M,) int
        Inliers of one essential matrix.
    num_matches : int
        Descriptor matches before verification.
    """

    i: int
    j: int
    idx_i: np.ndarray
    idx_j: np.ndarray
    num_matches: int

    @property
    def num_inliers(self) -> int:
        return len(self.idx_i)
