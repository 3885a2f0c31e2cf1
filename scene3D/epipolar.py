"""Moved to :mod:`scene3D.geometry.epipolar`; this alias goes in the next release."""

import warnings

from .geometry.epipolar import *  # noqa: F401,F403

warnings.warn("scene3D.epipolar moved to scene3D.geometry.epipolar",
              DeprecationWarning, stacklevel=2)
