"""The dense part of a many-view page: the fused cloud's numbers, its layer of the 3D view
(the mesh instead when there is one), and a coloured thumbnail of each view's depth map.

It reads what :func:`scene3D.densify.densify` returned (the cloud, and the small depth maps
:mod:`scene3D.densify.preview` keeps); the colouring is the page's. As the view thins a
cloud to its bound, a mesh is simplified to :data:`MAX_VIEW_FACES` triangles
(:func:`scene3D.densify.mesh.simplify_mesh`).
"""

from __future__ import annotations

import functools
from dataclasses import dataclass

import cv2
import numpy as np

from ..densify.fusion import DenseCloud
from ..densify.mesh import Mesh, simplify_mesh
from ..densify.pipeline import DenseResult
from ..densify.preview import DepthPreview
from ..viz.drawing import encode_jpeg
from .page import Page
from .viewer import MAX_VIEW_POINTS, CloudLayer, MeshLayer

__all__ = ["MAX_VIEW_FACES", "DenseRun", "dense_clouds", "dense_meshes", "dense_section",
           "depth_thumbnail"]

#: At most this many triangles of a mesh are sent to the browser (about 4 MB of page).
MAX_VIEW_FACES = 100_000

#: The grey of pixels without a depth (BGR).
_NO_DEPTH = (225, 225, 225)


@dataclass(frozen=True)
class DenseRun:
    """What a page shows of a dense run.

    Attributes
    ----------
    names : tuple of str
        The dense model's views, in the order of ``result.previews``.
    result : DenseResult
        :func:`scene3D.densify.densify`'s result (same world frame as the sparse model).
    mesh : Mesh or None
        The surface, when one was made.
    """

    names: tuple[str, ...]
    result: DenseResult
    mesh: Mesh | None = None

    @functools.cached_property
    def shown_mesh(self) -> Mesh | None:
        """The mesh as the 3D view shows it: at most :data:`MAX_VIEW_FACES` triangles
        (made once)."""
        return None if self.mesh is None else simplify_mesh(self.mesh, MAX_VIEW_FACES)


def dense_clouds(dense: DenseRun | DenseCloud | None) -> list[CloudLayer]:
    """The 3D view's layer of a dense cloud (thinned by the view to its bound,
    :data:`~scene3D.report.viewer.MAX_VIEW_POINTS` with the sparse points); none for no
    cloud, or for a run with a mesh (:func:`dense_meshes` shows that instead)."""
    if dense is None or isinstance(dense, DenseRun) and dense.mesh is not None:
        return []
    cloud = dense.result.cloud if isinstance(dense, DenseRun) else dense
    return [CloudLayer("dense", cloud.points3d, cloud.colors, 1.5)]


def dense_meshes(dense: DenseRun | DenseCloud | None) -> tuple[MeshLayer, ...]:
    """The 3D view's layer of a dense run's mesh, simplified to :data:`MAX_VIEW_FACES`
    triangles; none without a mesh."""
    shown = dense.shown_mesh if isinstance(dense, DenseRun) else None
    if shown is None:
        return ()
    return (MeshLayer("mesh", shown.vertices, shown.faces, shown.colors),)


def depth_thumbnail(preview: DepthPreview) -> bytes:
    """A JPEG of a depth preview: near red, far blue (OpenCV's turbo colour map over the
    2nd to 98th percentile of its depths), light grey where there is no depth.

    Parameters
    ----------
    preview : DepthPreview

    Returns
    -------
    bytes
        JPEG, the preview's size.
    """
    depth = preview.depth
    valid = np.isfinite(depth)
    if valid.any():
        near, far = np.percentile(depth[valid], (2, 98))
        share = (far - np.where(valid, depth, far)) / max(float(far - near), 1e-12)
        level = np.clip(np.rint(255 * share), 0, 255).astype(np.uint8)
    else:
        level = np.zeros(depth.shape, np.uint8)
    image = cv2.applyColorMap(level, cv2.COLORMAP_TURBO)
    image[~valid] = _NO_DEPTH
    return encode_jpeg(image, quality=85)


def dense_section(page: Page, dense: DenseRun) -> None:
    """The "Dense cloud" section: its numbers, and a thumbnail of each view's depth map.

    Parameters
    ----------
    page : Page
    dense : DenseRun
    """
    names, result, mesh = dense.names, dense.result, dense.mesh
    page.heading("Dense cloud")
    maps = [p for p in result.previews if p is not None]
    rows = [("dense points", f"{result.cloud.num_points:,}",
             "fused points: each depth confirmed by at least two other views, one point a "
             "voxel"),
            ("voxel side", f"{result.voxel_size:.4g}", "the thinning grid's cell, in the "
             "model's units (about a pixel's footprint)"),
            ("depth maps", f"{len(maps)} of {len(names)}", "views with a depth map (a view "
             "that shares no sparse point with another gets none)")]
    if mesh is not None:
        rows.append(("mesh triangles", f"{len(mesh.faces):,}",
                     f"the surface in mesh.ply ({len(mesh.vertices):,} vertices)"))
    page.quantities(rows, "dense")
    if mesh is None:
        page.paragraph(f"The 3D view holds at most {MAX_VIEW_POINTS:,} points: the sparse "
                       "cloud whole, then the dense cloud thinned to evenly spaced points. "
                       "The files hold every point.", "note")
    else:
        shown = len(dense.shown_mesh.faces)
        page.paragraph(f"The 3D view shows the mesh instead of the dense cloud, with "
                       f"{shown:,} of its {len(mesh.faces):,} triangles (at most "
                       f"{MAX_VIEW_FACES:,}: nearby vertices merged). mesh.ply holds them "
                       "all.", "note")
    if not maps:
        return
    page.heading("Depth maps")
    page.open_row()
    for name, preview in zip(names, result.previews):
        if preview is None:
            continue
        width, height = preview.image_size
        share = preview.valid_pixels / max(width * height, 1)
        page.figure(depth_thumbnail(preview), f"{name}: depth at {share:.0%} of the pixels",
                    alt=f"depth map of {name}")
    page.close_row()
    page.paragraph("Each view's depth map, small: near in red, far in blue (each map "
                   "coloured over its own depths), grey where no depth was found.", "note")
