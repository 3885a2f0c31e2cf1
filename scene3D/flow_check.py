"""Moved to :mod:`scene3D.twoview.flow_check`; this alias goes in the next release."""

import warnings

from .twoview.flow_check import *  # noqa: F401,F403

warnings.warn("scene3D.flow_check moved to scene3D.twoview.flow_check",
              DeprecationWarning, stacklevel=2)
