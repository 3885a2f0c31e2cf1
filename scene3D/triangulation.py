"""Moved to :mod:`scene3D.geometry.triangulation`; this alias goes in the next release."""

import warnings

from .geometry.triangulation import *  # noqa: F401,F403

warnings.warn("scene3D.triangulation moved to scene3D.geometry.triangulation",
              DeprecationWarning, stacklevel=2)
