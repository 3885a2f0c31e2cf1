"""Stage 1: features once per image, as an independent task per image.

:func:`view_features` takes one image's source and returns its features: a pure
module-level function, so that an engine may run it anywhere (a path is read where
the task runs). Its inputs and outputs are small and picklable.
"""

from __future__ import annotations

import hashlib

import numpy as np

from ..features.matching import create_detector, detect_keypoints, to_gray
from ..geometry.conventions import FloatArray
from ..io.images import ImageSource, load_working_image
from ..twoview import sample_colors
from .view_data import ViewFeatures


def extract_features(img: np.ndarray, feature: str = "SIFT",
                     max_features: int = 8000) -> ViewFeatures:
    """Keypoints, descriptors, colours and keypoint sizes of one BGR image
    ``(H, W, 3) uint8`` (the detector of :func:`scene3D.features.image_features`).

    Parameters
    ----------
    img : (H, W, 3) uint8 ndarray
        BGR image as cv2 loads it.
    feature : str, default "SIFT"
        Detector name (:func:`scene3D.features.create_detector`).
    max_features : int, default 8000
        Most keypoints kept.

    Returns
    -------
    ViewFeatures
        Keypoints ``(N, 2) float64`` in pixels (OpenCV convention), descriptors, RGB
        colours and sizes.
    """
    detector, norm, _ = create_detector(feature, max_features)
    pixels, sizes, descriptors = detect_keypoints(to_gray(img), detector)
    return ViewFeatures(pixels, descriptors, sample_colors(img, pixels), norm, sizes=sizes)


def view_features(source: ImageSource, K: FloatArray, dist: FloatArray,
                  max_width: int | None, name: str, feature: str = "SIFT",
                  max_features: int = 8000
                  ) -> tuple[ViewFeatures, tuple[int, int], tuple[int, int], int]:
    """The task of one image: load it at the working size and extract its features.

    Parameters
    ----------
    source : path or (H, W[, C]) array
    K, dist : (3, 3), (k,)
        Native intrinsics and distortion (the image is undistorted first).
    max_width : int or None
        Halve while wider (:func:`scene3D.io.images.load_working_image`).

    Returns
    -------
    features, native_size, working_size, levels
        ``native_size`` and ``working_size`` are (width, height); ``levels`` halvings.
    """
    img, native, levels = load_working_image(source, K, dist, max_width, name)
    return (extract_features(img, feature, max_features), native,
            (int(img.shape[1]), int(img.shape[0])), levels)


def content_key(features: ViewFeatures) -> bytes:
    """A digest of a view's keypoints and descriptors: the same image gives the same key
    whatever its file is called, so sorting by it orders views independently of names.

    Parameters
    ----------
    features : ViewFeatures
        The view's keypoints and descriptors.

    Returns
    -------
    bytes
        A 16-byte BLAKE2b digest.
    """
    digest = hashlib.blake2b(digest_size=16)
    digest.update(np.ascontiguousarray(features.keypoints).tobytes())
    digest.update(np.ascontiguousarray(features.descriptors).tobytes())
    return digest.digest()
