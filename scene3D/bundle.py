"""Moved to :mod:`scene3D.optim.bundle`; this alias goes in the next release."""

import warnings

from .optim.bundle import *  # noqa: F401,F403

warnings.warn("scene3D.bundle moved to scene3D.optim.bundle",
              DeprecationWarning, stacklevel=2)
