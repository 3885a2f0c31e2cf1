"""Moved to :mod:`scene3D.io.exif`; this alias goes in the next release."""

import warnings

from .io.exif import *  # noqa: F401,F403

warnings.warn("scene3D.exif moved to scene3D.io.exif",
              DeprecationWarning, stacklevel=2)
