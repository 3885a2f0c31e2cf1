"""Moved to :mod:`scene3D.geometry.pose`; this alias goes in the next release."""

import warnings

from .geometry.pose import *  # noqa: F401,F403

warnings.warn("scene3D.pose moved to scene3D.geometry.pose",
              DeprecationWarning, stacklevel=2)
