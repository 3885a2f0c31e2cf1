"""Moved to :mod:`scene3D.viz.plotting`; this alias goes in the next release."""

import warnings

from .viz.plotting import *  # noqa: F401,F403

warnings.warn("scene3D.plotting moved to scene3D.viz.plotting",
              DeprecationWarning, stacklevel=2)
