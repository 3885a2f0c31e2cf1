"""Deprecated: moved to :mod:`scene3D.twoview.degeneracy`.

This alias of the old path goes in the next release; importing it warns once
(``DeprecationWarning``) with the new path.
"""

from .errors import warn_moved
from .twoview.degeneracy import *  # noqa: F401,F403

warn_moved(__name__, "scene3D.twoview.degeneracy")
