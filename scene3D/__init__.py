"""scene3D: two-view structure from motion and camera calibration.

After Chapter 4 of *OpenCV with Python Blueprints*, on OpenCV 5. The frames and
array conventions are stated once in :mod:`scene3D.geometry`.
"""

from .dense import DenseReconstruction, dense_point_cloud
from .errors import CalibrationError, DatasetError, ReconstructionError
from .features import FEATURE_MODES, Matches, find_matches
from .multiview import MultiViewReconstruction, reconstruct_views
from .scene import SceneReconstruction3D
from .twoview import TwoViewReconstruction, TwoViewSettings, reconstruct_from_matches

__version__ = "0.1.0"

__all__ = [
    "FEATURE_MODES",
    "CalibrationError",
    "DatasetError",
    "DenseReconstruction",
    "Matches",
    "MultiViewReconstruction",
    "ReconstructionError",
    "SceneReconstruction3D",
    "TwoViewReconstruction",
    "TwoViewSettings",
    "__version__",
    "dense_point_cloud",
    "find_matches",
    "reconstruct_from_matches",
    "reconstruct_views",
]
