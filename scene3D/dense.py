"""Dense reconstruction: semi-global matching on the rectified pair.

The disparity search range comes from the sparse reconstruction (the disparities
of the triangulated matches, with a margin), not from a magic constant. The
disparity map is cleaned with a left-right consistency check and speckle
filtering, then every valid pixel is triangulated in the rectified frame and
rotated back to the camera-1 frame. With ``|t| = 1`` the dense points have the
same scale as the sparse ones (units of the baseline).

Rectified geometry (``cv2.stereoRectify`` with ``CALIB_ZERO_DISPARITY``): both
rectified cameras share ``f`` and the principal point, rows correspond, and a
pixel ``(x, y)`` of image 1 with disparity ``d = x1 - x2`` lies at depth
``Z = f B / |d|`` with ``B = |t|``. (A mostly vertical baseline is rectified by
columns, ``d = y1 - y2``, and matched transposed.) Rectified image 2 is shifted along
the baseline by the start of the search range, so SGBM searches from zero disparity
however far the cameras converge; the shift is added back.
"""

from __future__ import annotations

import logging
from dataclasses import dataclass

import cv2
import numpy as np

from .errors import ReconstructionError
from .geometry.camera import validate_intrinsics
from .geometry.conventions import FloatArray, require_whole_number
from .geometry.rectification import (
    RectifiedPair,
    baseline_axis,
    rectify_pair,
    rectify_points,
    rectifying_transforms,
)
from .io.images import image_size

logger = logging.getLogger(__name__)

#: Disparities are kept where the left and right maps agree to this many pixels.
LR_TOLERANCE_PX = 1.0

#: A side of the search range counts as cutting off part of the scene when more than
#: this fraction of the valid disparities lie within 1 px of it: what lies beyond a
#: range gets matched at its edge. Measured on Middlebury Aloe, whose near leaves have
#: no sparse matches: 2.4 % at the top edge of the sparse range, 0.2 % once widened.
EDGE_PILE_UP_FRACTION = 0.01


@dataclass(frozen=True)
class DenseReconstruction:
    """A dense point cloud from one rectified pair.

    Attributes
    ----------
    points3d : (N, 3) float64
        Points in the camera-1 frame, in units of the baseline (like the sparse cloud).
    colors : (N, 3) uint8
        RGB from rectified image 1.
    pixels : (N, 2) float64
        Where each point is seen in rectified image 1.
    disparity : (H, W) float32
        Disparity ``x1 - x2`` of rectified image 1 in pixels (``y1 - y2`` when the
        baseline is mostly vertical: :func:`~scene3D.geometry.rectification.baseline_axis`), zero
        at infinity, NaN where invalid. Signed: negative throughout when image 2 is the
        left view (the book pair: -286 to -190 px), so select valid pixels with
        ``np.isfinite``, not ``> 0``. ``cv2.reprojectImageTo3D(disparity, Q)`` gives
        the points in the rectified camera-1 frame (:attr:`Q`).
    disparity_range : tuple[int, int]
        The searched range ``[min, max)`` of ``|disparity|`` (pixels; the matcher runs
        on the pair mirrored when image 2 is the left view).
    rectified : RectifiedPair
        The rectified pair; image 2 shifted along the baseline by the start of the
        search range (its ``P2`` says by how much), so the disparities between the two
        images, which its ``Q`` takes, run from zero up.
    """

    points3d: FloatArray
    colors: np.ndarray
    pixels: FloatArray
    disparity: np.ndarray
    disparity_range: tuple[int, int]
    rectified: RectifiedPair

    @property
    def num_points(self) -> int:
        return len(self.points3d)

    def __repr__(self) -> str:  # the arrays by their shapes: a cloud is 10^5 points
        h, w = self.disparity.shape[:2]
        return (f"DenseReconstruction({self.num_points} points, disparity {w}x{h}, "
                f"disparity_range={self.disparity_range})")

    @property
    def Q(self) -> FloatArray:
        """(4, 4) disparity-to-depth matrix for :attr:`disparity` (zero at infinity), for
        ``cv2.reprojectImageTo3D``; the rectified pair's ``Q`` takes the disparities
        between its shifted images instead."""
        Q = self.rectified.Q.copy()
        Q[3, 3] = 0.0  # both rectified cameras' principal points coincide before the shift
        return Q


def disparity_range(
    sparse_disparities: FloatArray, margin: float = 0.15, min_margin_px: int = 8
) -> tuple[int, int]:
    """``[min, max)`` search range covering the sparse disparities plus a margin.

    The range spans the 1st to 99th percentile widened by ``margin`` of its width
    (at least ``min_margin_px``) on each side, rounded out to a multiple of 16 as
    SGBM requires.

    Parameters
    ----------
    sparse_disparities : (N,) ndarray
        Disparities (px) of the sparse matches on the rectified images.
    margin : float, default 0.15
        Widening on each side, as a share of the range's width.
    min_margin_px : int, default 8
        Smallest widening (px).

    Returns
    -------
    (int, int)
        ``(lo, hi)`` in px, ``hi - lo`` a multiple of 16.
    """
    lo, hi = np.percentile(sparse_disparities, [1, 99])
    pad = max(margin * (hi - lo), min_margin_px)
    lo = int(np.floor(lo - pad))
    hi = int(np.ceil(hi + pad))
    width = int(np.ceil((hi - lo) / 16.0) * 16)
    return lo, lo + max(width, 16)


def require_searchable_range(lo: int, hi: int, width: int, offset: int = 0) -> None:
    """Raise :class:`ReconstructionError` when searching ``[lo, hi)`` on rectified images
    ``width`` pixels across the baseline, image 2 shifted by ``offset``
    (:func:`search_disparity`), would leave no column a disparity.

    SGBM gives no disparity to the leftmost ``hi - offset`` columns (their match would
    lie left of image 2) nor to the rightmost ``offset - lo``; a search wider than the
    image fails inside OpenCV. A range that wide comes from cameras that converge
    strongly on a scene deep in range, from an epipole in or near the image (the camera
    moved towards the scene), or from a pose too uncertain to rectify by.

    Parameters
    ----------
    lo, hi : int
        Disparity search range ``[lo, hi)`` (px).
    width : int
        Width (px) of the rectified images across the baseline.
    offset : int, default 0
        Shift (px) of image 2.

    Raises
    ------
    ReconstructionError
        ``"no_dense_range"``.
    """
    lost = max(hi - offset, 0) + max(offset - lo, 0)
    if lost >= width:
        raise ReconstructionError(
            "no_dense_range",
            f"dense matching cannot serve this pair: its sparse disparities span [{lo}, {hi}) "
            f"px, too wide a search for rectified images {width} px across (cameras that "
            "converge strongly on a scene deep in range, an epipole in or near the image, "
            "or a pose too uncertain to rectify by); the sparse result does not need it")


def sgbm_matcher(min_disp: int, num_disp: int, block: int) -> cv2.StereoSGBM:
    """OpenCV's semi-global matcher as :func:`compute_disparity` configures it.

    Parameters
    ----------
    min_disp : int
        The smallest disparity searched, in pixels.
    num_disp : int
        How many disparities are searched (a multiple of 16).
    block : int
        The odd side of the matched blocks, in pixels (the smoothness penalties
        ``P1 = 24 block^2`` and ``P2 = 96 block^2`` follow it).

    Returns
    -------
    cv2.StereoSGBM
        3-way SGBM, no left-right check of its own (:func:`compute_disparity` does it),
        no speckle filter; its disparities are in 1/16 pixel.
    """
    return cv2.StereoSGBM_create(
        minDisparity=min_disp, numDisparities=num_disp, blockSize=block,
        P1=8 * 3 * block * block, P2=32 * 3 * block * block, disp12MaxDiff=-1,
        uniquenessRatio=10, speckleWindowSize=0, mode=cv2.STEREO_SGBM_MODE_SGBM_3WAY,
    )


def compute_disparity(
    left: np.ndarray,
    right: np.ndarray,
    min_disparity: int,
    num_disparities: int,
    block_size: int = 5,
    speckle_window: int = 100,
    speckle_range_px: float = 2.0,
) -> np.ndarray:
    """SGBM disparity of ``left`` with a left-right check and speckle filtering.

    Parameters
    ----------
    left, right : (H, W, 3) uint8
        Rectified images; a left pixel ``x`` matches the right pixel ``x - d``.
    min_disparity, num_disparities : int
        Search range ``[min, min + num)``; ``num`` a multiple of 16.

    Returns
    -------
    (H, W) float32
        Disparities in pixels, NaN where invalid.
    """
    left_matcher = sgbm_matcher(min_disparity, num_disparities, block_size)
    disp_left = left_matcher.compute(left, right).astype(np.float32) / 16.0
    # The right view's disparities: mirrored, the right image becomes a left image whose
    # pixel x' matches x' - d with the same d, so the same range applies; mirror back.
    right_matcher = sgbm_matcher(min_disparity, num_disparities, block_size)
    disp_right = right_matcher.compute(right[:, ::-1].copy(), left[:, ::-1].copy())
    disp_right = disp_right[:, ::-1].astype(np.float32) / 16.0
    invalid_left = disp_left < min_disparity
    invalid_right = disp_right < min_disparity
    h, w = disp_left.shape
    xs = np.arange(w)[None, :] - np.rint(disp_left).astype(int)
    inside = (xs >= 0) & (xs < w)
    rows = np.arange(h)[:, None]
    partner = disp_right[rows, np.clip(xs, 0, w - 1)]
    partner_invalid = invalid_right[rows, np.clip(xs, 0, w - 1)]
    consistent = inside & ~partner_invalid & (np.abs(disp_left - partner) <= LR_TOLERANCE_PX)
    valid = ~invalid_left & consistent
    # Speckle filter on a 16x fixed-point copy, as OpenCV expects.
    fixed = np.where(valid, np.rint(disp_left * 16), (min_disparity - 1) * 16).astype(np.int16)
    cv2.filterSpeckles(fixed, (min_disparity - 1) * 16, speckle_window,
                       int(round(speckle_range_px * 16)))
    valid &= fixed >= min_disparity * 16
    return np.where(valid, disp_left, np.nan).astype(np.float32)


def range_edges_cut(disparity: np.ndarray, lo: int, hi: int) -> tuple[bool, bool]:
    """Whether valid disparities pile up against the low and the high end of ``[lo, hi)``.

    ``disparity`` is a map of :func:`compute_disparity` searched over ``[lo, hi)``
    (NaN where invalid); see :data:`EDGE_PILE_UP_FRACTION`.

    Parameters
    ----------
    disparity : (H, W) ndarray
        Disparity map (px), NaN where invalid.
    lo, hi : int
        The range it was searched over (px).

    Returns
    -------
    (bool, bool)
        Piled up at the low end, at the high end.
    """
    valid = disparity[np.isfinite(disparity)]
    if len(valid) == 0:
        return False, False
    return (bool(np.mean(valid <= lo + 1) > EDGE_PILE_UP_FRACTION),
            bool(np.mean(valid >= hi - 2) > EDGE_PILE_UP_FRACTION))


def search_disparity(
    left: np.ndarray, right: np.ndarray, lo: int, hi: int, block_size: int = 5,
    max_widenings: int = 2, offset: int = 0,
) -> tuple[np.ndarray, tuple[int, int]]:
    """:func:`compute_disparity` over ``[lo, hi)``, widened where it cuts the scene off.

    Sparse matches can miss part of a scene (close-up foliage, a blank near wall), so
    their range may stop short. A side where the result piles up
    (:func:`range_edges_cut`) moves out by half the range's width (a multiple of 16)
    and the pair is matched again, at most ``max_widenings`` times. The low side
    goes no lower than 0 (points at infinity); the high side no further than half the
    image width beyond ``offset``, since SGBM leaves the leftmost ``hi - offset`` columns
    without disparities.

    ``offset`` is how far ``right`` was shifted (``rectify_pair``'s ``shift2_px``): a
    disparity ``d`` lies ``d - offset`` apart in the images, so SGBM searches
    ``[lo - offset, hi - offset)`` and ``offset`` is added back.

    Returns the disparity map (H, W) float32 (zero at infinity) and the range ``(lo, hi)``
    it searched.

    Parameters
    ----------
    left, right : (H, W) uint8 ndarray
        Rectified grey images 1 and 2.
    lo, hi : int
        Starting range ``[lo, hi)`` (px), ``hi - lo`` a multiple of 16.
    block_size : int, default 5
        SGBM block size (px, odd).
    max_widenings : int, default 2
        Most widenings of the range.
    offset : int, default 0
        How far ``right`` was shifted (px).

    Returns
    -------
    disparity : (H, W) float32 ndarray
    range : (int, int)
    """
    def match(lo: int, hi: int) -> np.ndarray:
        return compute_disparity(left, right, lo - offset, hi - lo, block_size) + offset

    disparity = match(lo, hi)
    for _ in range(max_widenings):
        cut_low, cut_high = range_edges_cut(disparity, lo, hi)
        step = 16 * int(np.ceil((hi - lo) / 32))
        low_step = min(step, 16 * (lo // 16))  # the width stays a multiple of 16
        cut_low = cut_low and low_step > 0
        cut_high = cut_high and hi - offset + step <= left.shape[1] // 2
        if not (cut_low or cut_high):
            break
        lo, hi = lo - (low_step if cut_low else 0), hi + (step if cut_high else 0)
        logger.info("disparities pile up at the range's edge: widened to [%d, %d)", lo, hi)
        disparity = match(lo, hi)
    return disparity, (lo, hi)


def dense_point_cloud(
    img1: np.ndarray,
    img2: np.ndarray,
    K: FloatArray,
    R: FloatArray,
    t: FloatArray,
    sparse_pts1: FloatArray,
    sparse_pts2: FloatArray,
    block_size: int = 5,
) -> DenseReconstruction:
    """Dense, coloured point cloud of an undistorted pair with known relative pose.

    Parameters
    ----------
    img1, img2 : (H, W, 3) uint8
        Undistorted working images (BGR).
    K : (3, 3)
        Their intrinsics.
    R, t : (3, 3), (3,)
        ``x_cam2 = R x_cam1 + t``; ``|t|`` sets the scale of the result.
    sparse_pts1, sparse_pts2 : (M, 2)
        Pixels of reliable sparse matches, used to choose the disparity range.

    Returns
    -------
    DenseReconstruction

    block_size : int
        The matched block's side in pixels, odd (OpenCV's ``StereoSGBM``).

    Raises
    ------
    ReconstructionError
        ``"no_dense_range"`` when the sparse disparities need a search range wider than
        the images (:func:`require_searchable_range`);
        ``"no_dense_points"`` when no pixel passes the left-right check.
    ValueError
        The images are not colour images of one size, ``K``, ``R``, ``t`` are not a
        camera matrix, a rotation and a translation, or ``block_size`` is not an odd
        whole number.
    """
    if require_whole_number(block_size, "block_size") % 2 == 0:
        raise ValueError(f"`block_size` must be odd (a block centred on its pixel), got "
                         f"{block_size}")
    for name, img in (("img1", img1), ("img2", img2)):
        if not (isinstance(img, np.ndarray) and img.dtype == np.uint8 and img.ndim == 3
                and img.shape[2] == 3):
            got = f"{img.dtype} {img.shape}" if isinstance(img, np.ndarray) else type(img).__name__
            raise ValueError(f"`{name}` must be an (H, W, 3) uint8 BGR image, got {got}")
    if img1.shape != img2.shape:
        raise ValueError(f"`img1` and `img2` must have the same size, got {img1.shape[:2]} "
                         f"and {img2.shape[:2]} (H, W)")
    K = validate_intrinsics(K)
    R, t = np.asarray(R, np.float64), np.asarray(t, np.float64).reshape(-1)
    if R.shape != (3, 3) or t.shape != (3,) or not (np.all(np.isfinite(R))
                                                    and np.all(np.isfinite(t))):
        raise ValueError(f"`R` and `t` must be a finite (3, 3) rotation and (3,) translation, "
                         f"got shapes {R.shape} and {t.shape}")
    R1, R2, P1, P2, _ = rectifying_transforms(K, R, t, image_size(img1), alpha=0.0)
    # SGBM matches along rows; a pair rectified by columns (a mostly vertical baseline)
    # is matched transposed.
    axis = baseline_axis(P2)
    r1 = rectify_points(np.asarray(sparse_pts1, np.float64), K, R1, P1)
    r2 = rectify_points(np.asarray(sparse_pts2, np.float64), K, R2, P2)
    sparse_disp = r1[:, axis] - r2[:, axis]
    # SGBM searches positive disparities; if image 2 is the left view, mirror both.
    mirrored = float(np.median(sparse_disp)) < 0
    sign = -1 if mirrored else 1
    lo, hi = disparity_range(sign * sparse_disp)
    # Rectified image 2 shifted so that the search starts at zero: a converging pair's
    # disparities (zero at infinity) can exceed the image width.
    offset = lo
    logger.info("SGBM disparity range [%d, %d) from %d sparse points", lo, hi, len(sparse_disp))
    require_searchable_range(lo, hi, img1.shape[1 - axis], offset)
    rect = rectify_pair(img1, img2, K, R, t, alpha=0.0, shift2_px=sign * offset)
    left, right = rect.img1, rect.img2
    if axis == 1:
        left, right = left.transpose(1, 0, 2), right.transpose(1, 0, 2)
    if mirrored:
        left, right = left[:, ::-1], right[:, ::-1]
    left, right = np.ascontiguousarray(left), np.ascontiguousarray(right)
    disparity, (lo, hi) = search_disparity(left, right, lo, hi, block_size, offset=offset)
    if mirrored:
        disparity = -disparity[:, ::-1]
    if axis == 1:
        disparity = np.ascontiguousarray(disparity.T)
    ys, xs = np.nonzero(np.isfinite(disparity) & (np.abs(disparity) > 0.5))
    if len(xs) == 0:
        raise ReconstructionError(
            "no_dense_points", "dense matching found no pixel whose disparity the left and "
            "right views agree on; the sparse result does not need it")
    d = np.abs(disparity[ys, xs]).astype(np.float64)
    f, cx, cy = rect.P1[0, 0], rect.P1[0, 2], rect.P1[1, 2]
    baseline = float(np.linalg.norm(t))
    z = f * baseline / d
    rect_points = np.column_stack([(xs - cx) * z / f, (ys - cy) * z / f, z])
    points = rect_points @ rect.R1  # rectified camera-1 frame -> camera-1 frame (R1^T x)
    colors = rect.img1[ys, xs, ::-1].astype(np.uint8)
    return DenseReconstruction(points, colors, np.column_stack([xs, ys]).astype(np.float64),
                               disparity, (lo, hi), rect)
