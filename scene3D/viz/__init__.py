"""Figures: OpenCV drawings at the images' resolution and matplotlib figures.

- :mod:`scene3D.viz.drawing`: figures drawn with OpenCV into images (no matplotlib), which
  the command-line tools write as PNG;
- :mod:`scene3D.viz.plotting`: matplotlib ``Figure`` objects for notebooks and the book's
  methods, imported on first use so that the drawings never load matplotlib.
"""

from typing import TYPE_CHECKING, Any

from .drawing import (
    Raster,
    draw_disparity,
    draw_epipolar_lines,
    draw_optic_flow,
    draw_rectified,
    encode_jpeg,
    encode_png,
    frustum_corners,
    render_point_cloud,
    robust_extent,
    subsample_indices,
    titled,
)

if TYPE_CHECKING:
    from .plotting import (
        plot_calibration_coverage,
        plot_cameras_and_points,
        plot_disparity,
        plot_epipolar_lines,
        plot_optic_flow,
        plot_point_cloud,
        plot_raster,
        plot_rectified,
        plot_uncertainty_map,
        plot_view_errors,
    )

_LAZY = {
    "plot_calibration_coverage": "plotting",
    "plot_cameras_and_points": "plotting",
    "plot_disparity": "plotting",
    "plot_epipolar_lines": "plotting",
    "plot_optic_flow": "plotting",
    "plot_point_cloud": "plotting",
    "plot_raster": "plotting",
    "plot_rectified": "plotting",
    "plot_uncertainty_map": "plotting",
    "plot_view_errors": "plotting",
}


def __getattr__(name: str) -> Any:
    if name in _LAZY:
        import importlib

        return getattr(importlib.import_module(f".{_LAZY[name]}", __name__), name)
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")

__all__ = [
    "Raster", "draw_disparity", "draw_epipolar_lines", "draw_optic_flow", "draw_rectified",
    "encode_jpeg", "encode_png", "frustum_corners", "plot_calibration_coverage",
    "plot_cameras_and_points", "plot_disparity", "plot_epipolar_lines", "plot_optic_flow",
    "plot_point_cloud", "plot_raster", "plot_rectified", "plot_uncertainty_map", "plot_view_errors",
    "render_point_cloud", "robust_extent", "subsample_indices", "titled",
]
