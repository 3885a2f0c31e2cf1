"""Multi-view dense reconstruction: depth maps of many views fused into one cloud, and a mesh.

The stages, in the order :func:`densify` runs them:

- :mod:`~scene3D.densify.views`: each view's neighbours (shared sparse points, weighted by
  their triangulation angle) and depth range (its sparse points);
- :mod:`~scene3D.densify.sweep`: a depth map per view by plane sweep with ZNCC over its
  neighbours (one task per view on an engine, :mod:`scene3D.engines`);
- :mod:`~scene3D.densify.fusion`: normals, the multi-view consistency check (depth and
  reprojection) and voxel thinning into one cloud;
- :mod:`~scene3D.densify.preview`: a small copy of each depth map, kept for the report;
- :mod:`~scene3D.densify.mesh`: a screened Poisson surface, trimmed by density (Open3D,
  the optional extra ``mesh``).

The package is named ``densify`` beside :mod:`scene3D.dense`, which matches one rectified
pair (the book's ``--dense``); this one works from a sparse model of any number of views.
Frames as in :mod:`scene3D.geometry`: world-to-camera ``x_cam = R X + t``.
"""

from .fusion import DenseCloud, ViewDepth, fuse_depth_maps, voxel_thin
from .pipeline import (
    DenseInputError,
    DenseResult,
    DenseSettings,
    densify,
    image_paths,
    load_sparse_model,
)
from .preview import DepthPreview, depth_preview
from .sweep import SweepSettings, plane_sweep_depth
from .views import choose_neighbours, depth_range, neighbour_scores

__all__ = ["DenseCloud", "DenseInputError", "DenseResult", "DenseSettings", "DepthPreview",
           "SweepSettings", "ViewDepth", "choose_neighbours", "densify", "depth_preview",
           "depth_range", "fuse_depth_maps", "image_paths", "load_sparse_model",
           "neighbour_scores", "plane_sweep_depth", "voxel_thin"]
