"""Camera calibration from views of a chessboard, a ChArUco board or a grid of circles.

- :mod:`scene3D.calibration.views`: the photos or video frames, and the board found in
  each (the distinct views of a video);
- :mod:`scene3D.calibration.board`: board detection, the solve, coverage;
- :mod:`scene3D.calibration.uncertainty`: the covariance of the intrinsics and the
  projection-uncertainty map;
- :mod:`scene3D.calibration.pipeline`: the chain ``scene3d calibrate`` runs (solve,
  coverage, uncertainty map, warnings) and what the calibration file holds beside ``K``.

``views`` and ``pipeline`` are imported by their own paths.

The calibration file is read and written by :mod:`scene3D.io.calibration`. This package
replaces the module ``scene3D.calibration`` and re-exports its public names (with
:func:`load_calibration` and :func:`save_calibration`), and those of the uncertainty.
"""

from .board import (  # noqa: F401  (with the public names the module had beside __all__)
    MAX_RMS_PX,
    MIN_POINTS_PER_VIEW,
    PATTERNS,
    BoardSpec,
    CalibrationError,
    CalibrationResult,
    CameraCalibration,
    Detection,
    IntrinsicsCovariance,
    board_size_problem,
    calibrate,
    check_image,
    check_intrinsics_for_size,
    corner_coverage,
    coverage_warnings,
    detect_board,
    detect_charuco,
    detect_chessboard,
    detect_circles,
    intrinsics_covariance,
    is_real_number,
    is_whole_number,
    load_calibration,
    min_image_side_px,
    plural,
    save_calibration,
    subpixel_window,
)
from .uncertainty import (
    UncertaintyMap,
    format_px,
    projection_covariance,
    projection_sigma_px,
    reached_by_rays,
    uncertainty_map,
)

__all__ = [  # the module's __all__, then the uncertainty's
    "BoardSpec", "CalibrationResult", "CameraCalibration", "Detection", "calibrate",
    "corner_coverage", "coverage_warnings", "detect_board", "load_calibration",
    "min_image_side_px", "save_calibration", "subpixel_window", "board_size_problem",
    "MIN_POINTS_PER_VIEW", "IntrinsicsCovariance", "UncertaintyMap", "intrinsics_covariance",
    "format_px", "projection_covariance", "projection_sigma_px", "reached_by_rays",
    "uncertainty_map",
]
