"""Moved to :mod:`scene3D.io.images`; this alias goes in the next release."""

import warnings

from .io.images import *  # noqa: F401,F403

warnings.warn("scene3D.imageio moved to scene3D.io.images",
              DeprecationWarning, stacklevel=2)
