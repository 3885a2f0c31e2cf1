"""Moved to :mod:`scene3D.optim.refinement`; this alias goes in the next release."""

import warnings

from .optim.refinement import *  # noqa: F401,F403

warnings.warn("scene3D.refinement moved to scene3D.optim.refinement",
              DeprecationWarning, stacklevel=2)
