"""Moved to :mod:`scene3D.twoview.essential_fit`; this alias goes in the next release."""

import warnings

from .twoview.essential_fit import *  # noqa: F401,F403

warnings.warn("scene3D.essential_fit moved to scene3D.twoview.essential_fit",
              DeprecationWarning, stacklevel=2)
