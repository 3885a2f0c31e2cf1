"""Moved to :mod:`scene3D.twoview.degeneracy`; this alias goes in the next release."""

import warnings

from .twoview.degeneracy import *  # noqa: F401,F403

warnings.warn("scene3D.degeneracy moved to scene3D.twoview.degeneracy",
              DeprecationWarning, stacklevel=2)
