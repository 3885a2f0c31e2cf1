"""The calibration solve and the coverage of its views (pure functions).

:func:`calibrate` solves for ``K`` and the distortion from board detections
(:func:`scene3D.calibration.board.detect_board`) by Zhang's method through
``cv2.calibrateCameraExtended``, reports per-view RMS errors and parameter
uncertainties (the full covariance from :mod:`scene3D.calibration.uncertainty`), and can
drop outlier views and solve again; :func:`corner_coverage` and
:func:`coverage_warnings` tell which parts of the image the corners cover.

Sizes are (width, height) everywhere. Pixel conventions as in :mod:`scene3D.geometry`.
"""

from __future__ import annotations

import logging
from dataclasses import dataclass, field

import cv2
import numpy as np

from ..errors import CalibrationError
from ..geometry.camera import DISTORTION_NAMES, check_intrinsics_for_size
from ..geometry.conventions import FloatArray, is_whole_number
from ..io.calibration import CameraCalibration
from .board import MIN_POINTS_PER_VIEW, BoardSpec, Detection
from .uncertainty import IntrinsicsCovariance, intrinsics_covariance

logger = logging.getLogger(__name__)

__all__ = [
    "MAX_RMS_PX", "CalibrationResult", "calibrate", "corner_coverage", "coverage_warnings",
]

#: Largest RMS reprojection error (px) that :func:`calibrate` accepts: well above what
#: good boards give, well below what a wrong board size gives
#: (docs/benchmarks.md#calibration).
MAX_RMS_PX = 2.0


@dataclass(frozen=True)
class CalibrationResult:
    """Intrinsics estimated from several views, with their quality.

    Attributes
    ----------
    K : (3, 3) float64
    dist : (n,) float64
        OpenCV distortion coefficients (k1, k2, p1, p2, k3 by default).
    image_size : tuple[int, int]
        (width, height) the calibration holds for.
    rms_px : float
        Root-mean-square reprojection error over all corners of the kept views.
    per_view_errors_px : dict[str, float]
        RMS reprojection error of each kept view.
    std_intrinsics : dict[str, float]
        Standard deviations of fx, fy, cx, cy and the distortion coefficients: the
        diagonal of ``covariance`` (OpenCV's ``stdDeviationsIntrinsics`` when there is
        none).
    rejected_views : dict[str, float]
        Views dropped as outliers, with their error in the first solve.
    board : BoardSpec
    rvecs, tvecs : tuple of (3,) float64
        Board pose in each kept view (board-to-camera).
    covariance : IntrinsicsCovariance or None
        Full first-order covariance of ``fx, fy, cx, cy`` and the distortion, the board
        poses marginalised out (:func:`scene3D.calibration.uncertainty.intrinsics_covariance`);
        its diagonal gives ``std_intrinsics``.
    """

    K: FloatArray
    dist: FloatArray
    image_size: tuple[int, int]
    rms_px: float
    per_view_errors_px: dict[str, float]
    std_intrinsics: dict[str, float]
    rejected_views: dict[str, float]
    board: BoardSpec
    rvecs: tuple[FloatArray, ...] = field(default=(), repr=False)
    tvecs: tuple[FloatArray, ...] = field(default=(), repr=False)
    covariance: IntrinsicsCovariance | None = field(default=None, repr=False)

    def as_camera(self) -> CameraCalibration:
        return CameraCalibration(self.K, self.dist, self.image_size)


def _solve(detections: list[Detection], image_size: tuple[int, int], flags: int):
    object_points = [d.object_points.astype(np.float32) for d in detections]
    image_points = [d.image_points.astype(np.float32).reshape(-1, 1, 2) for d in detections]
    try:
        return cv2.calibrateCameraExtended(object_points, image_points, image_size, None, None,
                                           flags=flags)
    except cv2.error as exc:
        raise CalibrationError(f"OpenCV could not calibrate: {exc.err}") from exc


def calibrate(
    detections: list[Detection],
    image_size: tuple[int, int],
    board: BoardSpec,
    flags: int = 0,
    reject_outliers: bool = True,
    outlier_factor: float = 3.0,
    min_views: int = 3,
    max_rms_px: float | None = MAX_RMS_PX,
) -> CalibrationResult:
    """Calibrate a camera from board detections.

    Parameters
    ----------
    detections : list of Detection
        At least ``min_views`` views with at least 6 corners each.
    image_size : tuple[int, int]
        (width, height) of every view, ``img.shape[1::-1]`` (not ``img.shape[:2]``). Every
        detected corner must lie inside it.
    flags : int
        ``cv2.CALIB_*`` flags for ``calibrateCameraExtended``.
    reject_outliers : bool
        Drop views whose RMS error exceeds ``outlier_factor`` x the median, then
        solve again (once), keeping at least ``min_views``.
    max_rms_px : float or None
        Refuse a result whose RMS reprojection error exceeds this (None: no limit).

    Raises
    ------
    ValueError
        ``image_size`` is not two positive integers, or a detected corner lies outside
        it (the message says when width and height look swapped).
    CalibrationError
        Too few views, the solver fails or diverges, the corners do not fit one
        camera (RMS above ``max_rms_px``: typically a wrong board size, whose
        detections are not the board's corners), or the result is no camera's for
        ``image_size`` (:func:`scene3D.geometry.camera.check_intrinsics_for_size`, which
        :func:`load_calibration` applies too).
    """
    image_size = _check_image_size(image_size, detections)
    views = [d for d in detections if len(d.image_points) >= MIN_POINTS_PER_VIEW]
    if len(views) < min_views:
        raise CalibrationError(
            f"need at least {min_views} usable views of the board, got {len(views)}"
        )
    names = [d.name for d in views]
    rms, K, dist, rvecs, tvecs, std_int, _, per_view = _solve(views, image_size, flags)
    errors = per_view.ravel()
    rejected: dict[str, float] = {}
    if reject_outliers and len(views) > min_views:
        limit = outlier_factor * float(np.median(errors))
        bad = errors > limit
        if bad.any() and (~bad).sum() >= min_views:
            rejected = {n: float(e) for n, e, b in zip(names, errors, bad) if b}
            logger.info("dropping %d outlier view(s): %s", len(rejected), ", ".join(rejected))
            views = [d for d, b in zip(views, bad) if not b]
            names = [d.name for d in views]
            rms, K, dist, rvecs, tvecs, std_int, _, per_view = _solve(views, image_size, flags)
            errors = per_view.ravel()
    if not np.all(np.isfinite(K)) or K[0, 0] <= 0 or K[1, 1] <= 0 or not np.isfinite(rms):
        raise CalibrationError(f"the calibration diverged (rms={rms})")
    if max_rms_px is not None and rms > max_rms_px:
        raise CalibrationError(
            f"the corners do not fit one camera: RMS reprojection error {rms:.2f} px over "
            f"{len(views)} views, above the limit of {max_rms_px:g} px",
            reason="corners_do_not_fit", rms_px=float(rms),
        )
    try:  # what load_calibration will check: a file it would refuse is not written
        check_intrinsics_for_size(K, image_size)
    except ValueError as exc:
        raise CalibrationError(f"the calibration is no camera's for image_size "
                               f"{image_size[0]}x{image_size[1]}: {exc}") from exc
    dist = dist.ravel().astype(np.float64)
    std = std_int.ravel()
    std_names = ("fx", "fy", "cx", "cy") + DISTORTION_NAMES
    std_intrinsics = {n: float(s) for n, s in zip(std_names, std[: 4 + len(dist)])}
    try:
        covariance = intrinsics_covariance([d.object_points for d in views],
                                           [d.image_points for d in views], K, dist, rvecs,
                                           tvecs, flags)
    except ValueError as exc:  # flags the covariance does not model
        logger.warning("no covariance of the intrinsics: %s", exc)
        covariance = None
    if covariance is not None:
        # The same on a well-posed calibration; where the lens is poorly determined
        # OpenCV's understate the distortion's by orders of magnitude
        # (docs/benchmarks.md#calibration).
        std_intrinsics = covariance.std()
    return CalibrationResult(
        K=K.astype(np.float64), dist=dist, image_size=tuple(image_size), rms_px=float(rms),
        per_view_errors_px={n: float(e) for n, e in zip(names, errors)},
        std_intrinsics=std_intrinsics, rejected_views=rejected, board=board,
        rvecs=tuple(np.ravel(r).astype(np.float64) for r in rvecs),
        tvecs=tuple(np.ravel(t).astype(np.float64) for t in tvecs),
        covariance=covariance,
    )


def _check_image_size(image_size: tuple[int, int], detections: list[Detection]
                      ) -> tuple[int, int]:
    """``image_size`` as ``(width, height)`` ints once every detected corner lies inside it.

    Raises ``ValueError`` naming the likely swap of width and height (``img.shape[:2]``
    is ``(height, width)``) when the swapped size would hold the corners.
    """
    if (isinstance(image_size, (str, bytes)) or not hasattr(image_size, "__len__")
            or len(image_size) != 2
            or not all(is_whole_number(v) and v > 0 for v in image_size)):
        raise ValueError(f"`image_size` must be (width, height), two positive integers, "
                         f"got {image_size!r}")
    w, h = int(image_size[0]), int(image_size[1])
    points = [np.asarray(d.image_points, dtype=np.float64).reshape(-1, 2) for d in detections]
    points = [p for p in points if len(p)]
    if not points:
        return w, h
    lo = np.min([p.min(axis=0) for p in points], axis=0)
    hi = np.max([p.max(axis=0) for p in points], axis=0)

    def holds(width: int, height: int) -> bool:  # pixel centres at integers: edges at -0.5
        return bool(np.all(lo >= -0.5) and hi[0] <= width - 0.5 and hi[1] <= height - 0.5)

    if holds(w, h):
        return w, h
    reach = (f"detected corners span x = {lo[0]:.0f} to {hi[0]:.0f}, y = {lo[1]:.0f} to "
             f"{hi[1]:.0f} px")
    if holds(h, w):
        raise ValueError(f"`image_size` {w}x{h} does not hold the corners ({reach}), but "
                         f"{h}x{w} does: pass (width, height) = ({h}, {w}); img.shape[:2] is "
                         "(height, width)")
    raise ValueError(f"`image_size` {w}x{h} does not hold the corners ({reach}): it must be "
                     "the (width, height) of the images the corners were found in")


def corner_coverage(
    image_points: list[FloatArray], image_size: tuple[int, int], grid: tuple[int, int] = (8, 6)
) -> np.ndarray:
    """Corners per cell of a ``grid`` (columns, rows) laid over the image: ``(rows, cols) int``.

    Parameters
    ----------
    image_points : list of (N_v, 2) ndarray
        Detected corners of each view (pixels).
    image_size : (int, int)
        ``(width, height)`` in px.
    grid : (int, int), default (8, 6)
        ``(columns, rows)`` of cells.

    Returns
    -------
    (rows, cols) int ndarray
    """
    cols, rows = grid
    counts = np.zeros((rows, cols), dtype=int)
    w, h = image_size
    for pts in image_points:
        cx = np.clip((pts[:, 0] / w * cols).astype(int), 0, cols - 1)
        cy = np.clip((pts[:, 1] / h * rows).astype(int), 0, rows - 1)
        np.add.at(counts, (cy, cx), 1)
    return counts


def coverage_warnings(counts: np.ndarray) -> list[str]:
    """Warnings about empty parts of the image, from :func:`corner_coverage` counts.

    Parameters
    ----------
    counts : (rows, cols) int ndarray
        Corners per cell.

    Returns
    -------
    list of str
    """
    warnings = []
    border = np.concatenate([counts[0], counts[-1], counts[1:-1, 0], counts[1:-1, -1]])
    empty_border = float(np.mean(border == 0))
    if empty_border > 0.25:
        warnings.append(
            f"{empty_border:.0%} of the image border has no corners: distortion is decided "
            "there, so add views with the board near the edges and corners"
        )
    empty_total = float(np.mean(counts == 0))
    if empty_total > 0.5:
        warnings.append(f"{empty_total:.0%} of the image has no corners at all")
    return warnings
