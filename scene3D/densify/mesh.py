"""A surface from the fused cloud: Open3D's screened Poisson reconstruction, trimmed by
density (the optional extra ``mesh``: ``pip install 'scene3D[mesh]'``).

Screened Poisson (Kazhdan and Hoppe, 2013) fits a watertight surface to oriented points;
where no point supports it (the sky, the back of a facade) it still closes the surface, with
vertices of low density (how many points lie near them). The vertices below the
``trim_quantile`` of the density are removed with their faces.
"""

from __future__ import annotations

import importlib.util
from dataclasses import dataclass

import numpy as np

from .fusion import DenseCloud

#: How to get Open3D, for messages.
MESH_INSTALL_HINT = "install the extra: pip install 'scene3D[mesh]' (Open3D)"


class MissingMeshExtraError(ImportError):
    """Open3D is not installed (:data:`MESH_INSTALL_HINT`)."""


def require_open3d() -> None:
    """Raise :class:`MissingMeshExtraError` unless Open3D can be imported."""
    if importlib.util.find_spec("open3d") is None:
        raise MissingMeshExtraError(f"a mesh needs Open3D: {MESH_INSTALL_HINT}")


@dataclass(frozen=True)
class Mesh:
    """A triangle mesh.

    Attributes
    ----------
    vertices : (V, 3) float64
        World frame.
    faces : (F, 3) int64
        Vertex indices of each triangle.
    colors : (V, 3) uint8
        RGB of each vertex.
    """

    vertices: np.ndarray
    faces: np.ndarray
    colors: np.ndarray


def poisson_mesh(cloud: DenseCloud, depth: int = 10, trim_quantile: float = 0.05) -> Mesh:
    """The screened Poisson surface of ``cloud`` (oriented by its normals), without the
    vertices whose density is below the ``trim_quantile`` quantile.

    Parameters
    ----------
    cloud : DenseCloud
        Points with normals.
    depth : int, default 10
        The octree's depth (the surface's resolution: ``2^depth`` cells across the cloud).
    trim_quantile : float, default 0.05
        Share of the least supported vertices removed.

    Returns
    -------
    Mesh

    Raises
    ------
    MissingMeshExtraError
        Open3D is not installed.
    ValueError
        Fewer than 100 points with normals (those without one are left out).
    """
    require_open3d()
    import open3d as o3d

    oriented = np.linalg.norm(cloud.normals, axis=1) > 0.5  # points without a normal: none
    if oriented.sum() < 100:
        raise ValueError(f"a mesh needs at least 100 points with normals, the cloud has "
                         f"{int(oriented.sum())}")
    o3d.utility.set_verbosity_level(o3d.utility.VerbosityLevel.Error)  # PoissonRecon's notes
    pcd = o3d.geometry.PointCloud()
    pcd.points = o3d.utility.Vector3dVector(np.asarray(cloud.points3d[oriented], np.float64))
    pcd.normals = o3d.utility.Vector3dVector(np.asarray(cloud.normals[oriented], np.float64))
    pcd.colors = o3d.utility.Vector3dVector(np.asarray(cloud.colors[oriented], np.float64)
                                            / 255.0)
    mesh, densities = o3d.geometry.TriangleMesh.create_from_point_cloud_poisson(
        pcd, depth=depth)
    densities = np.asarray(densities)
    mesh.remove_vertices_by_mask(densities < np.quantile(densities, trim_quantile))
    return _from_open3d(mesh)


def _from_open3d(mesh) -> Mesh:
    """An Open3D ``TriangleMesh`` with vertex colours as a :class:`Mesh` (RGB ``uint8``)."""
    colors = np.clip(np.rint(np.asarray(mesh.vertex_colors) * 255), 0, 255).astype(np.uint8)
    return Mesh(np.asarray(mesh.vertices, np.float64), np.asarray(mesh.triangles, np.int64),
                colors)


def simplify_mesh(mesh: Mesh, max_faces: int) -> Mesh:
    """``mesh`` with at most ``max_faces`` triangles, by vertex clustering (Open3D): the
    vertices in each cell of a grid merged into one, their mean position and colour.

    The cell's side starts from the mesh's area (a cell holds about two triangles of a
    flat surface) and grows until the bound holds. Clustering takes about a second for
    four million triangles; quadric decimation, which keeps shapes better, a minute.

    Parameters
    ----------
    mesh : Mesh
    max_faces : int
        The bound (at least 1).

    Returns
    -------
    Mesh
        ``mesh`` itself when it is within the bound.

    Raises
    ------
    MissingMeshExtraError
        Open3D is not installed.
    """
    if max_faces < 1:
        raise ValueError(f"`max_faces` must be at least 1, got {max_faces}")
    if len(mesh.faces) <= max_faces:
        return mesh
    require_open3d()
    import open3d as o3d

    corners = mesh.vertices[mesh.faces]  # (F, 3, 3)
    area = 0.5 * np.linalg.norm(np.cross(corners[:, 1] - corners[:, 0],
                                         corners[:, 2] - corners[:, 0]), axis=1).sum()
    full = o3d.geometry.TriangleMesh(o3d.utility.Vector3dVector(mesh.vertices),
                                     o3d.utility.Vector3iVector(mesh.faces.astype(np.int32)))
    full.vertex_colors = o3d.utility.Vector3dVector(mesh.colors / 255.0)
    cell = np.sqrt(2 * max(area, 1e-30) / max_faces)
    while True:
        small = full.simplify_vertex_clustering(
            voxel_size=cell, contraction=o3d.geometry.SimplificationContraction.Average)
        faces = len(small.triangles)
        if faces <= max_faces:
            break
        cell *= 1.1 * np.sqrt(faces / max_faces)
    return _from_open3d(small)
