"""Feature detection and matching between two images.

Modes (case-insensitive): ``"SIFT"`` (default), ``"SURF"`` (the book's choice;
patented and missing from the pip wheels, so it falls back to SIFT with one
warning), ``"ORB"``, ``"AKAZE"`` and ``"flow"`` (corners tracked by pyramidal
Lucas-Kanade with a forward-backward check).

Descriptor matches pass Lowe's ratio test and a mutual (cross) check.
"""

from __future__ import annotations

import logging
import time
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass, field

import cv2
import numpy as np

from .geometry import FloatArray

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
        is one correspondence.
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
    """Return the canonical spelling of a feature mode, or raise ``ValueError``."""
    for valid in FEATURE_MODES:
        if isinstance(mode, str) and mode.lower() == valid.lower():
            return valid
    raise ValueError(
        f"unknown feature mode {mode!r}; valid modes are {', '.join(FEATURE_MODES)}"
    )


def create_detector(mode: str, max_features: int = 8000) -> tuple[cv2.Feature2D, int, str]:
    """Build the detector for a descriptor mode.

    Returns
    -------
    detector, norm, name
        The OpenCV detector, the descriptor norm for matching, and the name of
        the detector that will run (``"SIFT"`` for an unavailable SURF).
    """
    global _warned_surf
    mode = normalize_feature_mode(mode)
    if mode == "SURF":
        try:
            return cv2.xfeatures2d.SURF_create(400), cv2.NORM_L2, "SURF"
        except (cv2.error, AttributeError):
            if not _warned_surf:
                logger.warning(
                    "SURF is patented and not in this OpenCV build; using SIFT instead"
                )
                _warned_surf = True
            mode = "SIFT"
    if mode == "SIFT":
        return cv2.SIFT_create(nfeatures=max_features), cv2.NORM_L2, "SIFT"
    if mode == "ORB":
        return cv2.ORB_create(nfeatures=max_features), cv2.NORM_HAMMING, "ORB"
    if mode == "AKAZE":
        # OpenCV 5 moved AKAZE to the contrib module xfeatures2d.
        factory = getattr(cv2, "AKAZE_create", None) or cv2.xfeatures2d.AKAZE_create
        return factory(), cv2.NORM_HAMMING, "AKAZE"
    raise ValueError(f"feature mode {mode!r} has no descriptor detector")


def match_descriptors(
    desc1: np.ndarray, desc2: np.ndarray, norm: int, ratio: float = 0.8
) -> tuple[np.ndarray, np.ndarray]:
    """Match descriptors with Lowe's ratio test and a mutual nearest-neighbour check.

    Returns
    -------
    idx1, idx2 : (M,) int arrays
        Indices into ``desc1`` and ``desc2`` of the accepted matches.
    """
    empty = np.zeros(0, dtype=int)
    if desc1 is None or desc2 is None or len(desc1) < 2 or len(desc2) < 2:
        return empty, empty
    matcher = cv2.BFMatcher(norm)
    forward = [pair for pair in matcher.knnMatch(desc1, desc2, k=2) if len(pair) == 2]
    passed = [best for best, second in forward if best.distance < ratio * second.distance]
    idx1 = np.array([m.queryIdx for m in passed], dtype=int)
    idx2 = np.array([m.trainIdx for m in passed], dtype=int)
    if len(idx1) == 0:
        return empty, empty
    # Mutual check: only the image-2 descriptors that won a ratio test need their own
    # nearest neighbour in image 1 (the same answer as matching all of them, for less work).
    candidates = np.unique(idx2)
    backward = matcher.match(desc2[candidates], desc1)
    best_back = np.full(len(desc2), -1, dtype=int)
    best_back[candidates[[m.queryIdx for m in backward]]] = [m.trainIdx for m in backward]
    mutual = best_back[idx2] == idx1
    return idx1[mutual], idx2[mutual]


def track_flow(
    gray1: np.ndarray,
    gray2: np.ndarray,
    max_corners: int = 4000,
    max_fb_error_px: float = 1.0,
) -> tuple[FloatArray, FloatArray, int]:
    """Track corners of ``gray1`` into ``gray2`` with pyramidal Lucas-Kanade.

    A track is kept only when tracking it back from image 2 lands within
    ``max_fb_error_px`` of where it started (forward-backward check).

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


def to_gray(img: np.ndarray) -> np.ndarray:
    """BGR or grey ``uint8`` to grey."""
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
    """
    mode = normalize_feature_mode(mode)
    gray1, gray2 = to_gray(img1), to_gray(img2)
    t0 = time.perf_counter()
    if mode == "flow":
        pts1, pts2, num_corners = track_flow(gray1, gray2)
        elapsed = time.perf_counter() - t0
        return Matches(pts1, pts2, "flow", (num_corners, len(pts2)),
                       {"features": elapsed, "matching": 0.0})

    # One detector per image, both run at once: OpenCV releases the GIL while it works.
    (det1, norm, name), (det2, _, _) = (create_detector(mode, max_features) for _ in range(2))
    with ThreadPoolExecutor(max_workers=2) as pool:
        future1 = pool.submit(det1.detectAndCompute, gray1, None)
        future2 = pool.submit(det2.detectAndCompute, gray2, None)
        (kp1, desc1), (kp2, desc2) = future1.result(), future2.result()
    t1 = time.perf_counter()
    idx1, idx2 = match_descriptors(desc1, desc2, norm, ratio)
    t2 = time.perf_counter()
    pts1 = np.array([kp1[i].pt for i in idx1], dtype=np.float64).reshape(-1, 2)
    pts2 = np.array([kp2[i].pt for i in idx2], dtype=np.float64).reshape(-1, 2)
    logger.debug("%s: %d + %d keypoints, %d matches", name, len(kp1), len(kp2), len(pts1))
    return Matches(pts1, pts2, name, (len(kp1), len(kp2)),
                   {"features": t1 - t0, "matching": t2 - t1})

