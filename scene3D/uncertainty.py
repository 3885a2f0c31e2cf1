"""Moved to :mod:`scene3D.optim.uncertainty`; this alias goes in the next release."""

import warnings

from .optim.uncertainty import *  # noqa: F401,F403

warnings.warn("scene3D.uncertainty moved to scene3D.optim.uncertainty",
              DeprecationWarning, stacklevel=2)
