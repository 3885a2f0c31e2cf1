"""Moved to :mod:`scene3D.geometry.rectification`; this alias goes in the next release."""

import warnings

from .geometry.rectification import *  # noqa: F401,F403

warnings.warn("scene3D.rectification moved to scene3D.geometry.rectification",
              DeprecationWarning, stacklevel=2)
