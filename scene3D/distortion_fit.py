"""Moved to :mod:`scene3D.twoview.distortion_fit`; this alias goes in the next release."""

import warnings

from .twoview.distortion_fit import *  # noqa: F401,F403

warnings.warn("scene3D.distortion_fit moved to scene3D.twoview.distortion_fit",
              DeprecationWarning, stacklevel=2)
