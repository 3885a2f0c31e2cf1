"""scene3D: two-view structure from motion and camera calibration.

After Chapter 4 of *OpenCV with Python Blueprints*, on OpenCV 5. The frames and
array conventions are stated once in :mod:`scene3D.geometry`.
"""

import logging
from typing import TYPE_CHECKING, Any

from .errors import CalibrationError, DatasetError, ReconstructionError

__version__ = "0.1.0"

# A library leaves the output of its log to the program (the logging HOWTO): without a
# handler configured, Python would print warnings to stderr through its last resort.
logging.getLogger(__name__).addHandler(logging.NullHandler())

# The public names below are imported on first use: ``import scene3D`` stays cheap, and
# the command-line entry points can set up the process before numpy and OpenCV load.
_LAZY = {
    "FEATURE_MODES": "features", "Matches": "features", "find_matches": "features",
    "SceneReconstruction3D": "scene",
    "TwoViewGeometry": "twoview", "TwoViewReconstruction": "twoview",
    "TwoViewSettings": "twoview", "reconstruct_from_matches": "twoview",
    "DenseReconstruction": "dense", "dense_point_cloud": "dense",
    "MultiViewReconstruction": "multiview", "reconstruct_views": "multiview",
}

if TYPE_CHECKING:
    from .dense import DenseReconstruction, dense_point_cloud
    from .features.matching import FEATURE_MODES, Matches, find_matches
    from .multiview import MultiViewReconstruction, reconstruct_views
    from .scene import SceneReconstruction3D
    from .twoview import (
        TwoViewGeometry,
        TwoViewReconstruction,
        TwoViewSettings,
        reconstruct_from_matches,
    )


def __getattr__(name: str) -> Any:
    if name in _LAZY:
        import importlib

        return getattr(importlib.import_module(f".{_LAZY[name]}", __name__), name)
    raise AttributeError(f"module 'scene3D' has no attribute {name!r}")


__all__ = [
    "FEATURE_MODES",
    "CalibrationError",
    "DatasetError",
    "DenseReconstruction",
    "Matches",
    "MultiViewReconstruction",
    "ReconstructionError",
    "SceneReconstruction3D",
    "TwoViewGeometry",
    "TwoViewReconstruction",
    "TwoViewSettings",
    "__version__",
    "dense_point_cloud",
    "find_matches",
    "reconstruct_from_matches",
    "reconstruct_views",
]
