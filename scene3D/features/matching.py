"""Feature detection and matching between two images.

Modes (case-insensitive): ``"SIFT"`` (default), ``"SURF"`` (the book's choice;
patented and missing from the pip wheels, so it falls back to SIFT with one
warning), ``"ORB"``, ``"AKAZE"`` and ``"flow"`` (corners tracked by pyramidal
Lucas-Kanade with a forward-backward check).

Descriptor matches pass Lowe's ratio test and a mutual (cross) check.

SIFT is built with ``enable_precise_upscale=True``. OpenCV's default doubles the image
with linear interpolation at pixel centres, then reports keypoints as if that image
were aligned with the original's pixel grid. Every keypoint then comes out 0.25 px
right and 0.25 px down of where it is (opencv/opencv#23123). A mirror test shows it:
a keypoint and its twin in the flipped image disagree by 0.5 px. The precise upscale
puts every second pixel of the doubled image on an original pixel, and the bias is
gone. The test suite checks this.
"""

from __future__ import annotations

import logging
import os
import time
from collections.abc import Sequence
from dataclasses import dataclass, field

import cv2
import numpy as np

from ..geometry.conventions import FloatArray, require_real_number, require_whole_number

logger = logging.getLogger(__name__)

FEATURE_MODES = ("SIFT", "SURF", "ORB", "AKAZE", "flow")
_warned_surf = False


@dataclass(frozen=True)
class Matches:
    """Point correspondences between image 1 and image 2.

    Attributes
    ----------
    pts1, pts2 : (N, 2) float64
        Matched pixel coordinates in the two (working) images; row ``i`` of each
        is one correspondence. SIFT gives a keypoint one descriptor per dominant
        orientation, so a correspondence can be listed twice, once per orientation
        (about one match in ten); the two-view core counts it once
        (:func:`scene3D.twoview.reconstruct_from_matches`).
    feature : str
        The detector that actually ran (``"SIFT"`` when SURF was asked for but
        is unavailable).
    num_keypoints : tuple[int, int]
        Keypoints (or corners) found in each image.
    timings_s : dict[str, float]
        Seconds spent in ``"features"`` and ``"matching"``.
    """

    pts1: FloatArray
    pts2: FloatArray
    feature: str
    num_keypoints: tuple[int, int]
    timings_s: dict[str, float] = field(default_factory=dict)

    def __len__(self) -> int:
        return len(self.pts1)


def normalize_feature_mode(mode: str) -> str:
    """Return the canonical spelling of a feature mode, or raise ``ValueError``.

    Parameters
    ----------
    mode : str
        A feature mode of :data:`FEATURE_MODES`, any case.

    Returns
    -------
    str

    Raises
    ------
    ValueError
        For an unknown mode.
    """
    for valid in FEATURE_MODES:
        if isinstance(mode, str) and mode.lower() == valid.lower():
            return valid
    raise ValueError(
        f"unknown feature mode {mode!r}; valid modes are {', '.join(FEATURE_MODES)}"
    )


def resolve_feature_mode(mode: str) -> str:
    """The canonical name of the detector that runs for ``mode``: ``"SIFT"`` for SURF
    when this OpenCV build lacks it (it is patented; warned once), else ``mode``'s own.

    Raises ``ValueError`` for an unknown mode.

    Parameters
    ----------
    mode : str
        A feature mode of :data:`FEATURE_MODES`, any case.

    Returns
    -------
    str
    """
    global _warned_surf
    mode = normalize_feature_mode(mode)
    if mode != "SURF" or surf_available():
        return mode
    if not _warned_surf:
        logger.warning("SURF is patented and not in this OpenCV build; using SIFT instead")
        _warned_surf = True
    return "SIFT"


def surf_available() -> bool:
    """Whether this OpenCV build has SURF (patented; in the contrib builds only).

    Returns
    -------
    bool
        False: ``"SURF"`` runs SIFT instead (:func:`resolve_feature_mode`).
    """
    try:
        cv2.xfeatures2d.SURF_create(400)
    except (cv2.error, AttributeError):
        return False
    return True


def create_detector(mode: str, max_features: int = 8000) -> tuple[cv2.Feature2D, int, str]:
    """Build the detector for a descriptor mode.

    Parameters
    ----------
    mode : str
        A descriptor mode of :data:`FEATURE_MODES`.
    max_features : int, default 8000
        Keypoint budget of SIFT and ORB.


    Returns
    -------
    detector, norm, name
        The OpenCV detector, the descriptor norm for matching, and the name of
        the detector that will run (``"SIFT"`` for an unavailable SURF,
        :func:`resolve_feature_mode`).
    """
    mode = resolve_feature_mode(mode)
    if mode == "SURF":
        return cv2.xfeatures2d.SURF_create(400), cv2.NORM_L2, "SURF"
    if mode == "SIFT":
        # The precise upscale removes OpenCV's 0.25 px keypoint bias (module docstring).
        sift = cv2.SIFT_create(nfeatures=max_features, enable_precise_upscale=True)
        return sift, cv2.NORM_L2, "SIFT"
    if mode == "ORB":
        return cv2.ORB_create(nfeatures=max_features), cv2.NORM_HAMMING, "ORB"
    if mode == "AKAZE":
        # OpenCV 5 moved AKAZE to the contrib module xfeatures2d.
        factory = getattr(cv2, "AKAZE_create", None) or cv2.xfeatures2d.AKAZE_create
        return factory(), cv2.NORM_HAMMING, "AKAZE"
    raise ValueError(f"feature mode {mode!r} has no descriptor detector")


def _detect(gray: np.ndarray, detector: cv2.Feature2D
            ) -> tuple[Sequence[cv2.KeyPoint], FloatArray, np.ndarray]:
    """The detector's keypoints, their pixels ``(N, 2)`` float64 and descriptors ``(N, D)``
    (``(0, D)`` of the detector's type when it finds nothing: a blank image)."""
    keypoints, descriptors = detector.detectAndCompute(gray, None)
    pixels = cv2.KeyPoint_convert(keypoints) if keypoints else np.zeros((0, 2))
    if descriptors is None:  # OpenCV's answer for no keypoints
        dtype = np.float32 if detector.descriptorType() == cv2.CV_32F else np.uint8
        descriptors = np.zeros((0, detector.descriptorSize()), dtype=dtype)
    return keypoints, np.asarray(pixels, dtype=np.float64).reshape(-1, 2), descriptors


def detect_features(gray: np.ndarray, detector: cv2.Feature2D) -> tuple[FloatArray, np.ndarray]:
    """Keypoint pixels ``(N, 2)`` float64 and descriptors ``(N, D)`` of one grey image.

    Parameters
    ----------
    gray : (H, W) uint8 ndarray
        Grey image.
    detector : cv2.Feature2D
        From :func:`create_detector`.

    Returns
    -------
    pixels : (N, 2) float64 ndarray
        OpenCV pixel convention.
    descriptors : (N, D) ndarray
    """
    _, pixels, descriptors = _detect(gray, detector)
    return pixels, descriptors


def detect_keypoints(gray: np.ndarray, detector: cv2.Feature2D
                     ) -> tuple[FloatArray, FloatArray, np.ndarray]:
    """:func:`detect_features` with each keypoint's size: pixels ``(N, 2)`` float64,
    sizes ``(N,)`` float64 (``cv2.KeyPoint.size``, the diameter in pixels of the
    region described, which grows with the keypoint's scale) and descriptors ``(N, D)``.
    The many-view pipeline weighs its observations by the size
    (:mod:`scene3D.multiview.weights`); the two-view path does not need it.

    Parameters
    ----------
    gray : (H, W) uint8 ndarray
        Grey image.
    detector : cv2.Feature2D
        From :func:`create_detector`.

    Returns
    -------
    pixels : (N, 2) float64 ndarray
    sizes : (N,) float64 ndarray
    descriptors : (N, D) ndarray
    """
    keypoints, pixels, descriptors = _detect(gray, detector)
    return pixels, np.array([k.size for k in keypoints], dtype=np.float64), descriptors


@dataclass(frozen=True)
class ImageFeatures:
    """Keypoints and descriptors of one image, computed once to match with others.

    Attributes
    ----------
    pixels : (N, 2) float64
        Keypoint positions in the image.
    descriptors : (N, D) array
        float32 for SIFT/SURF, uint8 for ORB/AKAZE; ``(0, D)`` when nothing was found.
    feature : str
        The detector that ran (``"SIFT"`` for an unavailable SURF).
    norm : int
        The descriptor distance, ``cv2.NORM_L2`` or ``cv2.NORM_HAMMING``.
    seconds : float
        Time spent detecting and describing.
    """

    pixels: FloatArray
    descriptors: np.ndarray
    feature: str
    norm: int
    seconds: float


def image_features(img: np.ndarray, mode: str = "SIFT", max_features: int = 8000
                   ) -> ImageFeatures:
    """Detect and describe the keypoints of one BGR or grey ``uint8`` image.

    ``mode`` is a descriptor mode of :data:`FEATURE_MODES` (not ``"flow"``, which
    tracks between two images); ``max_features`` is the budget of SIFT and ORB.

    Parameters
    ----------
    img : (H, W, 3) or (H, W) uint8 ndarray
        BGR or grey image.
    mode : str, default "SIFT"
        Descriptor mode.
    max_features : int, default 8000
        Keypoint budget.

    Returns
    -------
    ImageFeatures
    """
    img = check_image(img, "img")
    t0 = time.perf_counter()
    detector, norm, name = create_detector(mode, max_features)
    pixels, descriptors = detect_features(to_gray(img), detector)
    return ImageFeatures(pixels, descriptors, name, norm, time.perf_counter() - t0)


def match_features(f1: ImageFeatures, f2: ImageFeatures, ratio: float = 0.8) -> Matches:
    """Correspondences between two images' features (:func:`match_descriptors`).

    ``timings_s["features"]`` is the detection time of both images, whether or not
    it was spent for this pair alone.

    Parameters
    ----------
    f1, f2 : ImageFeatures
        Features of images 1 and 2, of one detector.
    ratio : float, default 0.8
        Lowe's ratio test threshold.

    Returns
    -------
    Matches
        ``pts1, pts2`` ``(N, 2)`` pixels.

    Raises
    ------
    ValueError
        If the features come from different detectors.
    """
    if (f1.feature, f1.norm) != (f2.feature, f2.norm):
        raise ValueError(f"cannot match {f1.feature} features with {f2.feature} features")
    t0 = time.perf_counter()
    idx1, idx2 = match_descriptors(f1.descriptors, f2.descriptors, f1.norm, ratio)
    elapsed = time.perf_counter() - t0
    n1, n2 = len(f1.pixels), len(f2.pixels)
    logger.debug("%s: %d + %d keypoints, %d matches", f1.feature, n1, n2, len(idx1))
    return Matches(f1.pixels[idx1], f2.pixels[idx2], f1.feature, (n1, n2),
                   {"features": f1.seconds + f2.seconds, "matching": elapsed})


def match_descriptors(
    desc1: np.ndarray, desc2: np.ndarray, norm: int, ratio: float = 0.8
) -> tuple[np.ndarray, np.ndarray]:
    """Match descriptors with Lowe's ratio test and a mutual nearest-neighbour check.

    Parameters
    ----------
    desc1, desc2 : (N1, D), (N2, D) arrays
        Descriptors of image 1 and image 2 (float32 for SIFT/SURF, uint8 for binary ones).
    norm : int
        ``cv2.NORM_L2`` or ``cv2.NORM_HAMMING``.

    Returns
    -------
    idx1, idx2 : (M,) int arrays
        Indices into ``desc1`` and ``desc2`` of the accepted matches.
    """
    empty = np.zeros(0, dtype=int)
    if desc1 is None or desc2 is None or len(desc1) < 2 or len(desc2) < 2:
        return empty, empty
    if norm == cv2.NORM_L2 and desc1.dtype == np.float32 and desc2.dtype == np.float32:
        return _match_l2(desc1, desc2, ratio)
    matcher = cv2.BFMatcher(norm)
    forward = [pair for pair in matcher.knnMatch(desc1, desc2, k=2) if len(pair) == 2]
    passed = [best for best, second in forward if best.distance < ratio * second.distance]
    idx1 = np.array([m.queryIdx for m in passed], dtype=int)
    idx2 = np.array([m.trainIdx for m in passed], dtype=int)
    if len(idx1) == 0:
        return empty, empty
    # Mutual check: only the image-2 descriptors that won a ratio test need their own
    # nearest neighbour in image 1 (the same answer as matching all of them, for less work).
    candidates = np.flatnonzero(np.bincount(idx2, minlength=len(desc2)))
    backward = matcher.match(desc2[candidates], desc1)
    best_back = np.full(len(desc2), -1, dtype=int)
    best_back[candidates[[m.queryIdx for m in backward]]] = [m.trainIdx for m in backward]
    mutual = best_back[idx2] == idx1
    return idx1[mutual], idx2[mutual]


def _match_l2(desc1: np.ndarray, desc2: np.ndarray, ratio: float,
              block_rows: int = 512) -> tuple[np.ndarray, np.ndarray]:
    """:func:`match_descriptors` for float descriptors, from one matrix product.

    Squared distances ``|a|^2 + |b|^2 - 2 a.b`` come from BLAS, a block of rows at a
    time (memory ``block_rows * N2`` floats); both directions' nearest neighbours are
    read off the same distances. Blocks of 512 rows keep the column-wise minimum (a
    strided scan) in cache, faster than larger blocks (docs/benchmarks.md#whole-process-speed).
    SIFT descriptors hold integers
    below 2^9, so every sum stays below 2^24 and the float32 distances are exact: the
    matches are those of ``cv2.BFMatcher`` (knnMatch + cross check), found several
    times faster.
    """
    norms2 = np.einsum("ij,ij->i", desc2, desc2)
    n1, n2 = len(desc1), len(desc2)
    nearest = np.empty(n1, dtype=np.intp)
    ratio_ok = np.empty(n1, dtype=bool)
    col_best = np.full(n2, np.inf, dtype=np.float32)
    col_arg = np.zeros(n2, dtype=np.intp)
    for start in range(0, n1, block_rows):
        block = desc1[start:start + block_rows]
        dist = block @ desc2.T  # (b, N2)
        dist *= -2.0
        dist += np.einsum("ij,ij->i", block, block)[:, None]
        dist += norms2
        rows = np.arange(len(block))
        j = dist.argmin(axis=1)
        best = np.maximum(dist[rows, j], 0.0)
        dist[rows, j] = np.inf
        second = dist.min(axis=1)
        dist[rows, j] = best
        nearest[start:start + len(block)] = j
        ratio_ok[start:start + len(block)] = best < ratio * ratio * second
        i = dist.argmin(axis=0)
        value = dist[i, np.arange(n2)]
        better = value < col_best
        col_best[better] = value[better]
        col_arg[better] = i[better] + start
    idx1 = np.flatnonzero(ratio_ok & (col_arg[nearest] == np.arange(n1)))
    return idx1, nearest[idx1]


def track_flow(
    gray1: np.ndarray,
    gray2: np.ndarray,
    max_corners: int = 4000,
    max_fb_error_px: float = 1.0,
) -> tuple[FloatArray, FloatArray, int]:
    """Track corners of ``gray1`` into ``gray2`` with pyramidal Lucas-Kanade.

    A track is kept only when tracking it back from image 2 lands within
    ``max_fb_error_px`` of where it started (forward-backward check).

    Parameters
    ----------
    gray1, gray2 : (H, W) uint8 ndarray
        Grey images 1 and 2.
    max_corners : int, default 4000
        Most corners detected in image 1.
    max_fb_error_px : float, default 1.0
        Largest forward-backward error (px).


    Returns
    -------
    pts1, pts2 : (N, 2) float64
        The kept tracks.
    num_corners : int
        Corners detected in image 1.
    """
    corners = cv2.goodFeaturesToTrack(
        gray1, maxCorners=max_corners, qualityLevel=0.01, minDistance=7, blockSize=7
    )
    if corners is None:
        return np.zeros((0, 2)), np.zeros((0, 2)), 0
    p1 = corners.astype(np.float32).reshape(-1, 1, 2)
    lk = dict(winSize=(21, 21), maxLevel=3,
              criteria=(cv2.TERM_CRITERIA_EPS | cv2.TERM_CRITERIA_COUNT, 30, 0.01))
    p2, st_fwd, _ = cv2.calcOpticalFlowPyrLK(gray1, gray2, p1, None, **lk)
    p1_back, st_back, _ = cv2.calcOpticalFlowPyrLK(gray2, gray1, p2, None, **lk)
    fb_error = np.linalg.norm((p1 - p1_back).reshape(-1, 2), axis=1)
    keep = (st_fwd.ravel() == 1) & (st_back.ravel() == 1) & (fb_error < max_fb_error_px)
    pts1 = p1.reshape(-1, 2)[keep].astype(np.float64)
    pts2 = p2.reshape(-1, 2)[keep].astype(np.float64)
    return pts1, pts2, len(p1)


def check_image(img: np.ndarray, name: str = "img") -> np.ndarray:
    """``img`` once it is known to be a BGR ``(H, W, 3)`` or grey ``(H, W)`` ``uint8`` image.

    Parameters
    ----------
    img : ndarray
        The image to check.
    name : str, default "img"
        Its name in messages.

    Returns
    -------
    ndarray


    Raises
    ------
    TypeError
        If ``img`` is not a numpy array: a path (read it with
        :func:`scene3D.io.images.read_image`) or None (what ``cv2.imread`` returns for a
        file it cannot read).
    ValueError
        If the array is empty, not ``uint8``, or not of shape ``(H, W)`` or ``(H, W, 3)``.
    """
    expected = f"`{name}` must be a uint8 image array (H, W) or (H, W, 3)"
    if isinstance(img, (str, os.PathLike)):
        raise TypeError(f"{expected}, got the path '{img}': read it with "
                        "scene3D.io.images.read_image(path)")
    if img is None:
        raise TypeError(f"{expected}, got None (cv2.imread returns None for a file it cannot "
                        "read; scene3D.io.images.read_image says why)")
    if not isinstance(img, np.ndarray):
        raise TypeError(f"{expected}, got {type(img).__name__}")
    if img.ndim not in (2, 3) or (img.ndim == 3 and img.shape[2] != 3) or img.size == 0:
        raise ValueError(f"{expected}, got shape {img.shape}")
    if img.dtype != np.uint8:
        raise ValueError(f"{expected}, got dtype {img.dtype} "
                         "(scene3D.io.images.to_bgr8 converts 16-bit images)")
    return img


def to_gray(img: np.ndarray) -> np.ndarray:
    """BGR or grey ``uint8`` to grey.

    Parameters
    ----------
    img : (H, W, 3) or (H, W) uint8 ndarray
        BGR or grey image.

    Returns
    -------
    (H, W) uint8 ndarray
    """
    return img if img.ndim == 2 else cv2.cvtColor(img, cv2.COLOR_BGR2GRAY)


def find_matches(
    img1: np.ndarray,
    img2: np.ndarray,
    mode: str = "SIFT",
    ratio: float = 0.8,
    max_features: int = 8000,
) -> Matches:
    """Detect and match features between two images.

    Parameters
    ----------
    img1, img2 : (H, W, 3) or (H, W) uint8
        The working images (BGR or grey).
    mode : str
        One of :data:`FEATURE_MODES` (case-insensitive).
    ratio : float
        Lowe's ratio-test threshold for descriptor modes.
    max_features : int
        Keypoint budget per image for SIFT and ORB.

    Returns
    -------
    Matches
        Correspondences in pixels of ``img1`` and ``img2``.

    Raises
    ------
    TypeError, ValueError
        If an image is not a ``uint8`` array of one of those shapes (a path, None, a
        float image; :func:`check_image`), ``mode`` is unknown, ``ratio`` is not in
        (0, 1] or ``max_features`` is not a whole number of at least 1.
    """
    mode = normalize_feature_mode(mode)
    require_real_number(ratio, "ratio", 0.0, 1.0)
    require_whole_number(max_features, "max_features")
    gray1 = to_gray(check_image(img1, "img1"))
    gray2 = to_gray(check_image(img2, "img2"))
    t0 = time.perf_counter()
    if mode == "flow":
        pts1, pts2, num_corners = track_flow(gray1, gray2)
        elapsed = time.perf_counter() - t0
        return Matches(pts1, pts2, "flow", (num_corners, len(pts2)),
                       {"features": elapsed, "matching": 0.0})

    # One image after the other: OpenCV parallelises inside detectAndCompute, and that
    # beats running the two images in two Python threads, which oversubscribe the cores
    # (docs/benchmarks.md#whole-process-speed).
    return match_features(image_features(gray1, mode, max_features),
                          image_features(gray2, mode, max_features), ratio)

