"""Moved to :mod:`scene3D.io.datasets`; this alias goes in the next release."""

import warnings

from .io.datasets import *  # noqa: F401,F403

warnings.warn("scene3D.datasets moved to scene3D.io.datasets",
              DeprecationWarning, stacklevel=2)
