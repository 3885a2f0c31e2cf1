"""Moved to :mod:`scene3D.calibration.uncertainty`; this alias goes in the next release."""

import warnings

from .calibration.uncertainty import *  # noqa: F401,F403
from .calibration.uncertainty import (  # noqa: F401  (public names beside __all__)
    CORNER_LIMIT_PX,
    INTRINSIC_NAMES,
    ROUND_TRIP_TOLERANCE_PX,
    worst_direction_sigma,
)

warnings.warn("scene3D.calibration_uncertainty moved to scene3D.calibration.uncertainty",
              DeprecationWarning, stacklevel=2)
