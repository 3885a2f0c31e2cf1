"""Moved to :mod:`scene3D.geometry.intrinsics_prior`; this alias goes in the next release."""

import warnings

from .geometry.intrinsics_prior import *  # noqa: F401,F403

warnings.warn("scene3D.intrinsics_prior moved to scene3D.geometry.intrinsics_prior",
              DeprecationWarning, stacklevel=2)
