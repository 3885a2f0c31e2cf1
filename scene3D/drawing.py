"""Moved to :mod:`scene3D.viz.drawing`; this alias goes in the next release."""

import warnings

from .viz.drawing import *  # noqa: F401,F403
from .viz.drawing import (  # noqa: F401  (public names beside __all__)
    PNG_FAST_PARAMS,
    RectifiedPair,
    camera_centers,
    epipolar_colors,
    epipolar_lines,
    require_whole_number,
)

warnings.warn("scene3D.drawing moved to scene3D.viz.drawing",
              DeprecationWarning, stacklevel=2)
