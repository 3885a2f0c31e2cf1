"""Moved to :mod:`scene3D.geometry.camera`; this alias goes in the next release."""

import warnings

from .geometry.camera import *  # noqa: F401,F403

warnings.warn("scene3D.camera moved to scene3D.geometry.camera",
              DeprecationWarning, stacklevel=2)
