"""Camera calibration from views of a chessboard, a ChArUco board or a grid of circles.

- :mod:`scene3D.calibration.views`: the photos or video frames, and the board found in
  each (the distinct views of a video);
- :mod:`scene3D.calibration.board`: the calibration targets and their detection;
- :mod:`scene3D.calibration.solve`: the solve and the coverage of its views;
- :mod:`scene3D.calibration.uncertainty`: the covariance of the intrinsics and the
  projection-uncertainty map;
- :mod:`scene3D.calibration.pipeline`: the chain ``scene3d calibrate`` runs (solve,
  coverage, uncertainty map, warnings) and what the calibration file holds beside ``K``.

``views`` and ``pipeline`` are imported by their own paths.

The calibration file is read and written by :mod:`scene3D.io.calibration`. This package
replaces the module ``scene3D.calibration`` and re-exports its public names (with
:func:`load_calibration` and :func:`save_calibration`), and those of the uncertainty.
"""

from ..errors import CalibrationError, plural  # noqa: F401  (the old module's names)
from ..features.matching import check_image  # noqa: F401
from ..geometry.camera import check_intrinsics_for_size  # noqa: F401
from ..geometry.conventions import is_real_number, is_whole_number  # noqa: F401
from ..io.calibration import CameraCalibration, load_calibration, save_calibration
from .board import (  # noqa: F401  (with the public names the module had beside __all__)
    MIN_POINTS_PER_VIEW,
    PATTERNS,
    BoardSpec,
    Detection,
    board_size_problem,
    detect_board,
    detect_charuco,
    detect_chessboard,
    detect_circles,
    min_image_side_px,
    subpixel_window,
)
from .solve import (  # noqa: F401
    MAX_RMS_PX,
    CalibrationResult,
    calibrate,
    corner_coverage,
    coverage_warnings,
)
from .uncertainty import (
    IntrinsicsCovariance,
    UncertaintyMap,
    format_px,
    intrinsics_covariance,
    projection_covariance,
    projection_sigma_px,
    reached_by_rays,
    uncertainty_map,
)

__all__ = [  # the old module's __all__, then the uncertainty's
    "BoardSpec", "CalibrationResult", "CameraCalibration", "Detection", "calibrate",
    "corner_coverage", "coverage_warnings", "detect_board", "load_calibration",
    "min_image_side_px", "save_calibration", "subpixel_window", "board_size_problem",
    "MIN_POINTS_PER_VIEW", "IntrinsicsCovariance", "UncertaintyMap", "intrinsics_covariance",
    "format_px", "projection_covariance", "projection_sigma_px", "reached_by_rays",
    "uncertainty_map",
]
