"""Moved to :mod:`scene3D.io.image_integrity`; this alias goes in the next release."""

import warnings

from .io.image_integrity import *  # noqa: F401,F403

warnings.warn("scene3D.image_integrity moved to scene3D.io.image_integrity",
              DeprecationWarning, stacklevel=2)
