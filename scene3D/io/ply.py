"""PLY point clouds and meshes: binary little-endian, RGB colours, optional normals.

MeshLab, Open3D and CloudCompare read what :func:`write_ply` writes; :func:`read_ply`
and :func:`read_ply_normals` read it back. Files are written atomically
(:mod:`scene3D.io.atomic`).
"""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np

from .atomic import atomic_write_bytes

_PLY_VERTEX = np.dtype([
    ("x", "<f4"), ("y", "<f4"), ("z", "<f4"),
    ("red", "u1"), ("green", "u1"), ("blue", "u1"),
])
#: A vertex with a normal (``nx, ny, nz``, as MeshLab and Open3D name them).
_PLY_VERTEX_NORMAL = np.dtype([
    ("x", "<f4"), ("y", "<f4"), ("z", "<f4"),
    ("nx", "<f4"), ("ny", "<f4"), ("nz", "<f4"),
    ("red", "u1"), ("green", "u1"), ("blue", "u1"),
])


def ply_bytes(points3d: np.ndarray, colors: np.ndarray | None = None,
              normals: np.ndarray | None = None, faces: np.ndarray | None = None) -> bytes:
    """Binary little-endian PLY of ``(N, 3)`` points with ``(N, 3) uint8`` RGB colours
    and, if given, ``(N, 3)`` normals and ``(F, 3)`` triangles (a mesh).

    Points without colours are written white. Coordinates and normals are float32.

    Parameters
    ----------
    points3d : (N, 3) array_like
        Points.
    colors : (N, 3) uint8 array_like or None, default None
        RGB colours; None for white.
    normals : (N, 3) array_like or None, default None
        Unit normals (``nx, ny, nz``); None for none.
    faces : (F, 3) int array_like or None, default None
        Vertex indices of each triangle; None for a point cloud.

    Returns
    -------
    bytes

    Raises
    ------
    ValueError
        If the shapes are wrong.
    """
    points3d = np.asarray(points3d, dtype=np.float64)
    if points3d.ndim != 2 or points3d.shape[1] != 3:
        raise ValueError(f"`points3d` must have shape (N, 3), got {points3d.shape}")
    if colors is None:
        colors = np.full((len(points3d), 3), 255, dtype=np.uint8)
    colors = np.asarray(colors)
    if colors.shape != points3d.shape:
        raise ValueError(f"`colors` must have shape {points3d.shape}, got {colors.shape}")
    if normals is not None and np.shape(normals) != points3d.shape:
        raise ValueError(f"`normals` must have shape {points3d.shape}, got {np.shape(normals)}")
    vertices = np.empty(len(points3d), dtype=_PLY_VERTEX if normals is None
                        else _PLY_VERTEX_NORMAL)
    for i, axis in enumerate("xyz"):
        vertices[axis] = points3d[:, i]
        if normals is not None:
            vertices[f"n{axis}"] = np.asarray(normals)[:, i]
    for i, channel in enumerate(("red", "green", "blue")):
        vertices[channel] = colors[:, i]
    header = (
        "ply\nformat binary_little_endian 1.0\ncomment written by scene3D\n"
        f"element vertex {len(points3d)}\n"
        "property float x\nproperty float y\nproperty float z\n"
        + ("" if normals is None else "property float nx\nproperty float ny\nproperty float nz\n")
        + "property uchar red\nproperty uchar green\nproperty uchar blue\n"
        + ("" if faces is None else f"element face {len(faces)}\n"
           "property list uchar int vertex_indices\n")
        + "end_header\n"
    )
    if faces is None:
        return header.encode("ascii") + vertices.tobytes()
    triangles = np.empty(len(faces), np.dtype([("n", "u1"), ("v", "<i4", (3,))]))
    triangles["n"] = 3
    triangles["v"] = np.asarray(faces).reshape(-1, 3)
    return header.encode("ascii") + vertices.tobytes() + triangles.tobytes()


def write_ply(
    path: str | os.PathLike, points3d: np.ndarray, colors: np.ndarray | None = None,
    normals: np.ndarray | None = None,
) -> Path:
    """Write a coloured point cloud as binary PLY (MeshLab, Open3D, CloudCompare read it).

    Parameters
    ----------
    path : str or os.PathLike
        Target file.
    points3d : (N, 3) array_like
        Points.
    colors : (N, 3) uint8 array_like or None, default None
        RGB colours; None for white.
    normals : (N, 3) array_like or None, default None
        Unit normals; None for none.

    Returns
    -------
    Path
    """
    return atomic_write_bytes(path, ply_bytes(points3d, colors, normals))


def read_ply(path: str | os.PathLike) -> tuple[np.ndarray, np.ndarray]:
    """Read a PLY written by :func:`write_ply`: ``(N, 3) float64`` points, ``(N, 3) uint8`` RGB
    (normals, if the file has them: :func:`read_ply_normals`).

    Parameters
    ----------
    path : str or os.PathLike
        A PLY file.

    Returns
    -------
    points : (N, 3) float64 ndarray
    colors : (N, 3) uint8 ndarray

    Raises
    ------
    ValueError
        If it is not a binary little-endian PLY file.
    """
    vertices = _ply_vertices(path)
    points = np.column_stack([vertices[a] for a in "xyz"]).astype(np.float64)
    colors = np.column_stack([vertices[c] for c in ("red", "green", "blue")])
    return points, colors


def _ply_vertices(path: str | os.PathLike) -> np.ndarray:
    """The vertex records of a PLY that :func:`write_ply` wrote, with or without normals."""
    data = Path(path).read_bytes()
    end = data.find(b"end_header\n")
    if not data.startswith(b"ply\n") or end < 0:
        raise ValueError(f"'{path}' is not a PLY file")
    header = data[:end].decode("ascii").splitlines()
    if "format binary_little_endian 1.0" not in header:
        raise ValueError(f"'{path}' is not binary little-endian PLY")
    count = next(int(line.split()[2]) for line in header if line.startswith("element vertex"))
    dtype = _PLY_VERTEX_NORMAL if "property float nx" in header else _PLY_VERTEX
    return np.frombuffer(data, dtype=dtype, count=count, offset=end + len("end_header\n"))


def read_ply_normals(path: str | os.PathLike) -> np.ndarray:
    """The normals ``(N, 3) float32`` of a PLY written by :func:`write_ply` with normals.

    Parameters
    ----------
    path : str or os.PathLike
        A PLY file.

    Returns
    -------
    (N, 3) float32 ndarray

    Raises
    ------
    ValueError
        If it is not a binary little-endian PLY file with normals.
    """
    vertices = _ply_vertices(path)
    if "nx" not in vertices.dtype.names:
        raise ValueError(f"'{path}' is a PLY file without normals")
    return np.column_stack([vertices[f"n{a}"] for a in "xyz"])
