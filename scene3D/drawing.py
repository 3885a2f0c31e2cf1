"""Deprecated: moved to :mod:`scene3D.viz.drawing`.

This alias of the old path goes in the next release; importing it warns once
(``DeprecationWarning``) with the new path.
"""

from .errors import warn_moved
from .viz.drawing import *  # noqa: F401,F403
from .viz.drawing import (  # noqa: F401  (public names beside __all__)
    PNG_FAST_PARAMS,
    RectifiedPair,
    camera_centers,
    epipolar_colors,
    epipolar_lines,
    require_whole_number,
)

warn_moved(__name__, "scene3D.viz.drawing")
