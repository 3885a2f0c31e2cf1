"""Moved to :mod:`scene3D.twoview.focal_fit`; this alias goes in the next release."""

import warnings

from .twoview.focal_fit import *  # noqa: F401,F403

warnings.warn("scene3D.focal_fit moved to scene3D.twoview.focal_fit",
              DeprecationWarning, stacklevel=2)
