"""Moved to :mod:`scene3D.optim.bundle_two_view`; this alias goes in the next release."""

import warnings

from .optim.bundle_two_view import *  # noqa: F401,F403

warnings.warn("scene3D.bundle_two_view moved to scene3D.optim.bundle_two_view",
              DeprecationWarning, stacklevel=2)
