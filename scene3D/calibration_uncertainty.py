"""Deprecated: moved to :mod:`scene3D.calibration.uncertainty`.

This alias of the old path goes in the next release; importing it warns once
(``DeprecationWarning``) with the new path.
"""

from .calibration.uncertainty import *  # noqa: F401,F403
from .calibration.uncertainty import (  # noqa: F401  (public names beside __all__)
    CORNER_LIMIT_PX,
    INTRINSIC_NAMES,
    ROUND_TRIP_TOLERANCE_PX,
    worst_direction_sigma,
)
from .errors import warn_moved

warn_moved(__name__, "scene3D.calibration.uncertainty")
