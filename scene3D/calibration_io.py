"""Moved to :mod:`scene3D.io.calibration`; this alias goes in the next release."""

import warnings

from .io.calibration import *  # noqa: F401,F403

warnings.warn("scene3D.calibration_io moved to scene3D.io.calibration",
              DeprecationWarning, stacklevel=2)
