"""Moved to :mod:`scene3D.evaluation.synthetic`; this alias goes in the next release."""

import warnings

from .evaluation.synthetic import *  # noqa: F401,F403

warnings.warn("scene3D.synthetic moved to scene3D.evaluation.synthetic",
              DeprecationWarning, stacklevel=2)
