"""Moved to :mod:`scene3D.optim.schur`; this alias goes in the next release."""

import warnings

from .optim.schur import *  # noqa: F401,F403

warnings.warn("scene3D.schur moved to scene3D.optim.schur",
              DeprecationWarning, stacklevel=2)
