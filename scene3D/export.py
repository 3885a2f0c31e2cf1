"""Moved to :mod:`scene3D.io.export`; this alias goes in the next release."""

import warnings

from .io.export import *  # noqa: F401,F403

warnings.warn("scene3D.export moved to scene3D.io.export",
              DeprecationWarning, stacklevel=2)
