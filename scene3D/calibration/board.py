"""Calibration targets and finding them in an image (pure functions).

:class:`BoardSpec` describes a chessboard, a ChArUco board or a grid of circles, and
:func:`detect_board` finds its corners in a grey image (:class:`Detection`, with
matching object points on the board plane ``z = 0``). The steps after it, usable one by
one from a notebook:

1. :func:`scene3D.calibration.solve.calibrate` solves for ``K`` and the distortion, and
   :func:`scene3D.calibration.solve.corner_coverage` tells which parts of the image the
   corners cover;
2. :func:`scene3D.io.calibration.save_calibration` /
   :func:`scene3D.io.calibration.load_calibration` read and write OpenCV FileStorage YAML;
3. :mod:`scene3D.calibration.uncertainty` gives the full covariance of the intrinsics
   and the projection-uncertainty map.

Sizes are (width, height) everywhere. Pixel conventions as in :mod:`scene3D.geometry`.
"""

from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np

from ..errors import plural
from ..features.matching import check_image
from ..geometry.conventions import FloatArray, is_real_number, is_whole_number

__all__ = [
    "BoardSpec", "Detection", "detect_board", "min_image_side_px", "subpixel_window",
    "board_size_problem", "MIN_POINTS_PER_VIEW",
]

#: The calibration targets :class:`BoardSpec` describes.
PATTERNS = ("chessboard", "charuco", "circles", "acircles")
_SUBPIX_CRITERIA = (cv2.TERM_CRITERIA_EPS | cv2.TERM_CRITERIA_COUNT, 30, 0.01)
#: Seed of OpenCV's RNG before ``findChessboardCornersSB``, which draws from it: a fixed
#: seed makes :func:`detect_board` give the same answer for the same image every time.
_SB_SEED = 0
#: Board points a view needs to count (:func:`scene3D.calibration.solve.calibrate`).
MIN_POINTS_PER_VIEW = 6


def _is_real(value: object) -> bool:
    """True for a finite real number (not a bool)."""
    return is_real_number(value) and bool(np.isfinite(value))


def board_size_problem(pattern: str, size: tuple[int, int]) -> str:
    """Why a board of ``size`` (columns, rows, as :class:`BoardSpec` counts them) cannot
    calibrate, or ``""``, naming the smallest board that can. A view needs
    :data:`MIN_POINTS_PER_VIEW` points; OpenCV's chessboard detector needs at least 3
    inner corners a side (3x3 is the smallest chessboard), the other targets 2 squares
    or circles a side (ChArUco 3x4 or 2x7 squares, circle grids 2x3).

    Parameters
    ----------
    pattern : str
        ``"chessboard"``, ``"charuco"``, ``"circles"`` or ``"acircles"``.
    size : (int, int)
        ``(columns, rows)`` as :class:`BoardSpec` counts them.

    Returns
    -------
    str
    """
    cols, rows = size
    if pattern == "chessboard":
        if min(cols, rows) < 3:
            return ("a chessboard needs at least 3 inner corners a side, 3x3 or larger "
                    "(OpenCV's detector)")
        return ""
    if min(cols, rows) < 2:
        if pattern == "charuco":
            return (f"a ChArUco board needs at least 2 squares a side and "
                    f"{MIN_POINTS_PER_VIEW} inner corners: 3x4, 2x7 or larger")
        return (f"a grid of circles needs at least 2 circles a side and "
                f"{MIN_POINTS_PER_VIEW} in all: 2x3 or larger")
    smallest = "3x4 or 2x7" if pattern == "charuco" else "2x3"
    points = (cols - 1) * (rows - 1) if pattern == "charuco" else cols * rows
    if points < MIN_POINTS_PER_VIEW:
        what = plural(points, "inner corner" if pattern == "charuco" else "point")
        return (f"the board has {what}; a view needs at least "
                f"{MIN_POINTS_PER_VIEW} (such as {smallest})")
    return ""


@dataclass(frozen=True)
class BoardSpec:
    """A calibration target.

    Attributes
    ----------
    pattern : str
        ``"chessboard"``, ``"charuco"``, ``"circles"`` (a symmetric grid of circles) or
        ``"acircles"`` (an asymmetric one, alternate rows offset by half a column, as
        OpenCV's ``acircles_pattern.png``).
    size : tuple[int, int]
        Chessboard: inner corners (columns, rows), e.g. the book's (9, 6).
        ChArUco: squares (columns, rows), e.g. (5, 7). Circle grids: circles per row and
        rows, e.g. (4, 11) for OpenCV's asymmetric pattern. Two integers >= 2.
    square_size_m : float
        Side of one square; for circle grids OpenCV's spacing: the distance between
        neighbouring centres of a symmetric grid, half the distance between centres
        in a row of an asymmetric one (the distance between rows). The default 1.0
        gives results in these units; only the extrinsics depend on it, never ``K``
        or the distortion.
    marker_size_m : float
        ChArUco only: side of the ArUco markers. A board with an even number of rows
        may have OpenCV's layout before 4.6; both are tried (:func:`detect_charuco`).
    dictionary : str
        ChArUco only: an ``cv2.aruco`` dictionary name such as ``"DICT_6X6_250"``.
    """

    pattern: str = "chessboard"
    size: tuple[int, int] = (9, 6)
    square_size_m: float = 1.0
    marker_size_m: float = 0.5
    dictionary: str = "DICT_6X6_250"

    def __post_init__(self) -> None:
        if self.pattern not in PATTERNS:
            raise ValueError(f"`pattern` must be one of {', '.join(map(repr, PATTERNS))}, got "
                             f"{self.pattern!r}")
        size = self.size
        if (isinstance(size, (str, bytes)) or not hasattr(size, "__len__") or len(size) != 2
                or not all(is_whole_number(v) for v in size)
                or min(size) < 2):
            raise ValueError(f"`size` must be two integers >= 2 (columns, rows), got {size!r}")
        object.__setattr__(self, "size", (int(size[0]), int(size[1])))
        problem = board_size_problem(self.pattern, self.size)
        if problem:
            raise ValueError(f"`size` {self.size[0]}x{self.size[1]}: {problem}")
        if not (_is_real(self.square_size_m) and self.square_size_m > 0):
            raise ValueError("`square_size_m` must be a finite positive number, got "
                             f"{self.square_size_m!r}")
        if self.pattern == "charuco":
            if not (_is_real(self.marker_size_m)
                    and 0 < self.marker_size_m < self.square_size_m):
                raise ValueError(
                    "`marker_size_m` must be positive and smaller than the square, got "
                    f"{self.marker_size_m} for squares of {self.square_size_m}"
                )
            if not (isinstance(self.dictionary, str) and hasattr(cv2.aruco, self.dictionary)):
                raise ValueError(f"unknown ArUco dictionary {self.dictionary!r}")

    def describe(self) -> str:
        cols, rows = self.size
        if self.pattern == "chessboard":
            return f"chessboard {cols}x{rows} inner corners, square {self.square_size_m:g} m"
        if self.pattern == "circles":
            return f"circles grid {cols}x{rows}, spacing {self.square_size_m:g} m"
        if self.pattern == "acircles":
            return f"asymmetric circles grid {cols}x{rows}, spacing {self.square_size_m:g} m"
        return (f"ChArUco {cols}x{rows} squares, square {self.square_size_m:g} m, "
                f"marker {self.marker_size_m:g} m, {self.dictionary}")

    def grid_object_points(self) -> FloatArray:
        """``(cols * rows, 3)`` positions of the grid's points (inner corners, circle
        centres) on the plane ``z = 0``, row by row, in OpenCV's order: ``(j, i, 0) * s``
        for column ``j`` of row ``i``; ``(2 j + i % 2, i, 0) * s`` for ``"acircles"``."""
        cols, rows = self.size
        j, i = np.meshgrid(np.arange(cols), np.arange(rows))
        x = 2 * j + i % 2 if self.pattern == "acircles" else j
        grid = np.column_stack([x.ravel(), i.ravel()]) * self.square_size_m
        return np.column_stack([grid, np.zeros(len(grid))])

    def charuco_board(self) -> cv2.aruco.CharucoBoard:
        dictionary = cv2.aruco.getPredefinedDictionary(getattr(cv2.aruco, self.dictionary))
        return cv2.aruco.CharucoBoard(self.size, self.square_size_m, self.marker_size_m,
                                      dictionary)


@dataclass(frozen=True)
class Detection:
    """Corners of the board found in one view.

    Attributes
    ----------
    name : str
        Where the view came from (file name, frame number).
    image_points : (N, 2) float64
        Corner pixels.
    object_points : (N, 3) float64
        The same corners on the board (plane ``z = 0``, in metres).
    method : str
        The detector that found them.
    """

    name: str
    image_points: FloatArray
    object_points: FloatArray
    method: str


#: Fewest pixels a square of the board can span and still be found.
_MIN_SQUARE_PX = 3
#: OpenCV's classic chessboard detector fails on a shorter side below this (its adaptive
#: threshold block, a tenth of the side, rounds to 1 px).
_MIN_DETECTOR_SIDE_PX = 15


def min_image_side_px(board: BoardSpec) -> int:
    """The shorter side (px) below which an image cannot show ``board``: its squares
    across the board's narrower way, at least 3 px each.

    Parameters
    ----------
    board : BoardSpec
        The board.

    Returns
    -------
    int
    """
    squares = min(board.size) + (0 if board.pattern == "charuco" else 1)
    return max(_MIN_DETECTOR_SIDE_PX, _MIN_SQUARE_PX * squares)


def subpixel_window(corners: FloatArray, size: tuple[int, int]) -> int:
    """Half-size of the ``cornerSubPix`` window for a chessboard grid of ``size`` corners.

    A quarter of the smallest corner spacing (clamped to 2..15 px): a window
    larger than a square lets the neighbouring corners pull the estimate away.

    Parameters
    ----------
    corners : (cols * rows, 2) ndarray
        Chessboard corners in row order (pixels).
    size : (int, int)
        ``(cols, rows)`` inner corners.

    Returns
    -------
    int
        Half-size in px.
    """
    cols, rows = size
    grid = corners.reshape(rows, cols, 2)
    spacing = min(np.linalg.norm(np.diff(grid, axis=1), axis=2).min(),
                  np.linalg.norm(np.diff(grid, axis=0), axis=2).min())
    return int(np.clip(round(0.25 * spacing), 2, 15))


def _refine(gray: np.ndarray, corners: FloatArray, half_window: int) -> FloatArray:
    refined = cv2.cornerSubPix(gray, corners.astype(np.float32).reshape(-1, 1, 2),
                               (half_window, half_window), (-1, -1), _SUBPIX_CRITERIA)
    return refined.reshape(-1, 2).astype(np.float64)


def detect_chessboard(gray: np.ndarray, board: BoardSpec) -> tuple[FloatArray, str] | None:
    """Inner corners of a chessboard, ``(cols * rows, 2)``, or None when not found.

    The classic detector runs first, with sub-pixel refinement in a window that
    scales with the corner spacing; when it fails, the sector-based detector
    (``findChessboardCornersSB``) runs, refined the same way. That detector draws
    from OpenCV's global RNG, which is reseeded (``cv2.setRNGSeed``) right before it
    so that an image gives the same answer on every call.

    Parameters
    ----------
    gray : (H, W) uint8 ndarray
        Grey image.
    board : BoardSpec
        A chessboard.

    Returns
    -------
    (corners, method) or None
        Corners ``(cols * rows, 2) float64`` (OpenCV pixels) and ``"classic"`` or
        ``"sector"``.
    """
    flags = cv2.CALIB_CB_ADAPTIVE_THRESH | cv2.CALIB_CB_NORMALIZE_IMAGE
    found, corners = cv2.findChessboardCorners(gray, board.size, flags=flags)
    method = "classic"
    if not found:
        sb_flags = cv2.CALIB_CB_EXHAUSTIVE | cv2.CALIB_CB_ACCURACY
        cv2.setRNGSeed(_SB_SEED)  # it samples from the global RNG: same image, same answer
        found, corners = cv2.findChessboardCornersSB(gray, board.size, flags=sb_flags)
        method = "sector"
    if not found or corners is None:
        return None
    corners = corners.reshape(-1, 2).astype(np.float64)
    return _refine(gray, corners, subpixel_window(corners, board.size)), method


def detect_circles(gray: np.ndarray, board: BoardSpec) -> FloatArray | None:
    """Centres ``(N, 2)`` of a grid of dark circles on a light board (or light on dark)
    in row order, or None.

    ``cv2.findCirclesGrid`` with OpenCV's blob detector first; if it finds no grid,
    with blobs up to the image's area shared among the circles (a circle is smaller
    than its share of a grid that fits the image; OpenCV's default stops at 5000 px, a
    circle 80 px across, which a board filling a photo exceeds, while no bound at all
    lets the board's outline merge into a circle and pull its centre off). Each is tried
    plain and with ``CALIB_CB_CLUSTERING``, which copes with stronger perspective. The
    centres are the blobs' centroids: under perspective a circle's image is an ellipse
    whose centroid lies a little off the projected centre, so circles should stay small
    in the image (measured on rendered boards in the calibration guide).

    Parameters
    ----------
    gray : (H, W) uint8 ndarray
        Grey image.
    board : BoardSpec
        A symmetric or asymmetric circle grid.

    Returns
    -------
    (N, 2) float64 ndarray or None
    """
    large = cv2.SimpleBlobDetector_Params()
    large.minArea = 10.0
    large.maxArea = max(large.maxArea, gray.shape[0] * gray.shape[1] / np.prod(board.size))
    base = (cv2.CALIB_CB_SYMMETRIC_GRID if board.pattern == "circles"
            else cv2.CALIB_CB_ASYMMETRIC_GRID)
    for params in (cv2.SimpleBlobDetector_Params(), large):
        for image in (gray, 255 - gray):  # dark circles, then light ones
            for flags in (base, base | cv2.CALIB_CB_CLUSTERING):
                found, centres = cv2.findCirclesGrid(
                    image, board.size, flags=flags,
                    blobDetector=cv2.SimpleBlobDetector_create(params))
                if found and centres is not None:
                    return centres.reshape(-1, 2).astype(np.float64)
    return None


def detect_charuco(gray: np.ndarray, board: BoardSpec, min_corners: int = MIN_POINTS_PER_VIEW
                   ) -> tuple[FloatArray, FloatArray, str] | None:
    """ChArUco corners ``(N, 2)``, their board points ``(N, 3)`` and the layout that
    found them (``"charuco"`` or ``"charuco-legacy"``), or None.

    OpenCV 4.6 changed where the markers of a board with an even number of rows sit;
    boards printed from earlier versions (and some board generators) have the old
    layout, in which the new one finds markers but no corner of a whole board. For such
    a size both layouts are tried and the one that finds more corners is kept, the
    current one on a tie (a partial view of an old board can give both the same
    corners one square apart: the same intrinsics, another board pose).

    Parameters
    ----------
    gray : (H, W) uint8 ndarray
        Grey image.
    board : BoardSpec
        A ChArUco board.
    min_corners : int, default MIN_POINTS_PER_VIEW
        Fewest corners accepted.
    """
    layouts = [("charuco", board.charuco_board())]
    if board.size[1] % 2 == 0:
        legacy = board.charuco_board()
        legacy.setLegacyPattern(True)
        layouts.append(("charuco-legacy", legacy))
    best = None
    for name, charuco in layouts:
        corners, ids, _, _ = cv2.aruco.CharucoDetector(charuco).detectBoard(gray)
        if corners is None or ids is None or len(ids) < min_corners:
            continue
        if best is None or len(ids) > len(best[1]):
            best = (corners, ids, name, charuco)
    if best is None:
        return None
    corners, ids, name, charuco = best
    all_points = np.asarray(charuco.getChessboardCorners(), dtype=np.float64).reshape(-1, 3)
    return corners.reshape(-1, 2).astype(np.float64), all_points[ids.ravel()], name


def detect_board(gray: np.ndarray, board: BoardSpec, name: str = "") -> Detection | None:
    """Find ``board`` in an image; None when it is not (fully) visible, or the image is
    too small to show it (:func:`min_image_side_px`).

    The result is deterministic: the chessboard fallback detector's random draws come
    from OpenCV's global RNG, which this reseeds (:func:`detect_chessboard`).

    Parameters
    ----------
    gray : (H, W) or (H, W, 3) uint8
        Grey, or BGR as cv2 loads it (converted to grey).
    board : BoardSpec
    name : str
        Stored in the :class:`Detection` (the file name, say).

    Raises
    ------
    TypeError, ValueError
        If ``gray`` is not such an array: None (``cv2.imread`` of a missing or unreadable
        file), a path, or a float image (:func:`scene3D.features.check_image`).
    """
    gray = check_image(gray, "gray")
    if not isinstance(board, BoardSpec):
        raise TypeError(f"`board` must be a BoardSpec, got {type(board).__name__}")
    if min(gray.shape[:2]) < min_image_side_px(board):
        return None
    if gray.ndim == 3:
        gray = cv2.cvtColor(gray, cv2.COLOR_BGR2GRAY)
    if board.pattern == "chessboard":
        found = detect_chessboard(gray, board)
        if found is None:
            return None
        corners, method = found
        return Detection(name, corners, board.grid_object_points(), method)
    if board.pattern in ("circles", "acircles"):
        centres = detect_circles(gray, board)
        if centres is None:
            return None
        return Detection(name, centres, board.grid_object_points(), "circles")
    found = detect_charuco(gray, board)
    if found is None:
        return None
    return Detection(name, *found)
