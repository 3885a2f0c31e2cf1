"""Writing results: atomic file writes, PLY point clouds, JSON summaries, figures.

Every writer goes through :func:`atomic_write_pieces` (or :func:`atomic_write_bytes`):
the data land in a temporary file beside the target that is renamed over it only when
complete, so an interrupted run never leaves a half-written file. Within
:func:`all_or_nothing` the renames wait until every file of the block is written, so a
run that fails while writing (a full disk, say) leaves the earlier results as they were,
not half replaced.
"""

from __future__ import annotations

import io
import json
import math
import os
import time
import warnings
from collections.abc import Iterable, Iterator
from contextlib import contextmanager
from contextvars import ContextVar
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

if TYPE_CHECKING:
    from matplotlib.figure import Figure

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


#: The renames that :func:`all_or_nothing` holds back: (temporary file, target) pairs.
_staged: ContextVar[list[tuple[Path, Path]] | None] = ContextVar("staged", default=None)


@contextmanager
def all_or_nothing() -> Iterator[None]:
    """Write the block's files (this module's writers) all, or, if it raises, none.

    Each file is written to its temporary name as usual; the renames over the targets
    wait for the end of the block and happen only if it succeeds (renames need no space,
    so they do not fail for want of it). If it raises, the temporary files are removed
    and every target keeps what it held. Within another such block it adds its files to
    that block's, placed (or not) when the outer block ends.
    """
    if _staged.get() is not None:
        yield
        return
    staged: list[tuple[Path, Path]] = []
    token = _staged.set(staged)
    try:
        yield
    except BaseException:
        for tmp, _ in staged:
            tmp.unlink(missing_ok=True)
        raise
    finally:
        _staged.reset(token)
    try:
        for tmp, path in staged:
            os.replace(tmp, path)
    finally:
        for tmp, _ in staged:
            tmp.unlink(missing_ok=True)


def place_file(tmp: Path, path: Path) -> None:
    """Rename the complete file ``tmp`` over ``path`` now, or at the end of the enclosing
    :func:`all_or_nothing` block.

    Parameters
    ----------
    tmp : Path
        The complete temporary file.
    path : Path
        Its target.
    """
    staged = _staged.get()
    if staged is not None:
        staged.append((tmp, path))
        return
    try:
        os.replace(tmp, path)
    finally:
        tmp.unlink(missing_ok=True)


def written_bytes(path: str | os.PathLike) -> bytes:
    """The content of a file this module wrote: within :func:`all_or_nothing`, from its
    temporary file while the rename waits; else from ``path``.

    Parameters
    ----------
    path : str or os.PathLike
        A file this module wrote.

    Returns
    -------
    bytes
    """
    path = Path(path)
    for tmp, target in reversed(_staged.get() or []):
        if target == path:
            return tmp.read_bytes()
    return path.read_bytes()


def check_target(path: Path) -> None:
    """Raise ``IsADirectoryError`` when a folder stands where the file ``path`` is to go
    (the rename over it would fail only after every other file was written).

    Parameters
    ----------
    path : Path
        Where a file is to be written.

    Raises
    ------
    IsADirectoryError
        A folder stands at ``path``.
    """
    if path.is_dir():
        raise IsADirectoryError(21, "a folder stands where this file is to be written",
                                str(path))


def atomic_write_bytes(path: str | os.PathLike, data: bytes) -> Path:
    """Write ``data`` to ``path`` through a temporary file and a rename.

    Parameters
    ----------
    path : str or os.PathLike
        Target file.
    data : bytes
        Its content.

    Returns
    -------
    Path
    """
    return atomic_write_pieces(path, (data,))


def atomic_write_pieces(path: str | os.PathLike, pieces: Iterable[bytes | Path]) -> Path:
    """Write ``pieces`` one after the other to ``path`` through a temporary file and a
    rename: bytes as they are, a :class:`~pathlib.Path` as that file's whole content.

    Files are copied by the kernel where it can (``os.copy_file_range`` on Linux), never
    read into Python: a report's plotly.js costs a few milliseconds that way, a tenth of
    reading, decoding, joining, encoding and writing it (docs/benchmarks.md#whole-process-speed).

    Parameters
    ----------
    path : str or os.PathLike
        Target file.
    pieces : iterable of bytes or Path
        Its content, in order.

    Returns
    -------
    Path
    """
    path = Path(path)
    check_target(path)
    # A name no other writer uses (pid and clock), created exclusively beside the target.
    tmp = path.with_name(f".{path.name}.{os.getpid()}.{time.monotonic_ns()}.tmp")
    try:
        fd = os.open(tmp, os.O_WRONLY | os.O_CREAT | os.O_EXCL, 0o644)
    except OSError as exc:  # named by the file the user asked for, not its temporary name
        raise OSError(exc.errno, exc.strerror, str(path)) from exc
    try:
        with os.fdopen(fd, "wb", buffering=0) as f:
            for piece in pieces:
                if isinstance(piece, Path):
                    _copy_file_into(piece, f)
                else:
                    _write_all(f, piece)
    except OSError as exc:  # a full disk, say
        tmp.unlink(missing_ok=True)
        raise OSError(exc.errno, exc.strerror, str(path)) from exc
    except BaseException:
        tmp.unlink(missing_ok=True)
        raise
    place_file(tmp, path)
    return path


def _write_all(target: io.RawIOBase, data: bytes) -> None:
    """Write all of ``data`` to the unbuffered ``target``, which may take less at a time."""
    view = memoryview(data)
    while view:
        view = view[target.write(view):]


def _copy_file_into(source: Path, target: io.RawIOBase) -> None:
    """Append the whole of ``source`` to the unbuffered, open ``target``."""
    with open(source, "rb") as src:
        left = os.fstat(src.fileno()).st_size
        if hasattr(os, "copy_file_range"):
            try:
                while left > 0:
                    copied = os.copy_file_range(src.fileno(), target.fileno(), left)
                    if copied == 0:
                        break
                    left -= copied
                return
            except OSError:  # a file system without it: copy through Python from here on
                pass
        while chunk := src.read(1 << 20):
            _write_all(target, chunk)


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


def _jsonable(value: Any) -> Any:
    """``value`` with numpy types made Python ones, and NaN / infinity made None (null):
    JSON has no such numbers, and other readers reject the ``NaN`` Python would write."""
    if isinstance(value, np.ndarray):
        return _jsonable(value.tolist())
    if isinstance(value, (np.floating, np.integer, np.bool_)):
        value = value.item()
    if isinstance(value, float) and not math.isfinite(value):
        return None
    if isinstance(value, dict):
        return {str(k): _jsonable(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [_jsonable(v) for v in value]
    if isinstance(value, Path):
        return str(value)
    return value


def write_json(path: str | os.PathLike, obj: dict) -> Path:
    """Write ``obj`` (numpy arrays allowed; NaN and infinity as null) as indented JSON.

    Parameters
    ----------
    path : str or os.PathLike
        Target file.
    obj : dict
        The values.

    Returns
    -------
    Path
    """
    text = json.dumps(_jsonable(obj), indent=2, allow_nan=False) + "\n"
    return atomic_write_bytes(path, text.encode("utf-8"))


def save_figure(fig: Figure, path: str | os.PathLike, dpi: int = 100) -> Path:
    """Render a matplotlib figure to PNG and write it atomically.

    Parameters
    ----------
    fig : Figure
        A matplotlib figure.
    path : str or os.PathLike
        Target PNG file.
    dpi : int, default 100
        Resolution.

    Returns
    -------
    Path
    """
    buffer = io.BytesIO()
    fig.savefig(buffer, format="png", dpi=dpi, bbox_inches="tight")
    return atomic_write_bytes(path, buffer.getvalue())


def write_png(path: str | os.PathLike, image: np.ndarray) -> Path:
    """Write a BGR ``(H, W, 3) uint8`` (or grey ``(H, W)``) image as PNG, atomically.

    Parameters
    ----------
    path : str or os.PathLike
        Target file.
    image : (H, W, 3) or (H, W) uint8 ndarray
        BGR or grey image.

    Returns
    -------
    Path


    Raises
    ------
    ValueError
        OpenCV cannot encode ``image``.
    """
    import cv2  # OpenCV only where an image is written

    ok, data = cv2.imencode(".png", np.asarray(image))
    if not ok:
        raise ValueError(f"cannot encode an image of shape {np.shape(image)} as PNG")
    return atomic_write_bytes(path, data.tobytes())


def colmap_image_name(name: str) -> str:
    """``name`` as COLMAP's text format can hold it: every space (any whitespace) as '_'.

    ``images.txt`` separates its fields by spaces and has no quoting, so COLMAP and
    pycolmap read a name with a space only up to it (``'IMG 1.jpg'`` as ``'IMG'``).

    Parameters
    ----------
    name : str
        An image name.

    Returns
    -------
    str
    """
    return "".join("_" if c.isspace() else c for c in name)


#: What :func:`colmap_text_files` warns: its replacement.
COLMAP_TEXT_FILES_DEPRECATION = (
    "scene3D.io.export.colmap_text_files is deprecated and goes in the next release: use "
    "scene3D.io.colmap.colmap_text(colmap_model_from_views(...)) or "
    "scene3D.io.colmap.write_colmap_text")


def colmap_text_files(
    names: list[str],
    K: np.ndarray,
    image_size: tuple[int, int],
    registered: np.ndarray,
    R: np.ndarray,
    t: np.ndarray,
    points3d: np.ndarray,
    colors: np.ndarray,
    obs_view: np.ndarray,
    obs_point: np.ndarray,
    obs_xy: np.ndarray,
    errors_px: np.ndarray,
) -> dict[str, str]:
    """A COLMAP text model (``cameras.txt``, ``images.txt``, ``points3D.txt``) as strings.

    Deprecated, and removed in the next release: this is the first writer, kept for
    callers of its old path. Use :func:`scene3D.io.colmap.colmap_text` of
    :func:`scene3D.io.colmap.colmap_model_from_views` (the same arguments without
    ``errors_px``, which it computes), or :func:`scene3D.io.colmap.write_colmap_text`:
    every number to full precision, and read back by :func:`scene3D.io.colmap.read_colmap_text`.
    Calling it raises a ``DeprecationWarning`` that names them.

    One PINHOLE camera; image poses world-to-camera as quaternion ``(qw, qx, qy, qz)``
    and translation. COLMAP puts pixel centres at ``+0.5``, so principal point and
    2D points are shifted by half a pixel from the OpenCV convention used elsewhere.
    Image names are written as :func:`colmap_image_name` gives them: a space, which
    the format cannot hold, becomes '_' (so such a name no longer matches its file).

    Parameters
    ----------
    names : list of str
        The views' image names, ``V`` of them.
    K : (3, 3) ndarray
        Intrinsics shared by the views (OpenCV pixels).
    image_size : (int, int)
        ``(width, height)`` in px.
    registered : (V,) bool ndarray
        Views in the model.
    R : (V, 3, 3) ndarray
        World-to-camera rotations.
    t : (V, 3) ndarray
        World-to-camera translations.
    points3d : (P, 3) ndarray
        World points.
    colors : (P, 3) uint8 ndarray
        RGB colours.
    obs_view, obs_point : (O,) int ndarray
        View and point of each observation.
    obs_xy : (O, 2) ndarray
        Observed pixels (OpenCV convention).
    errors_px : (P,) ndarray
        Each point's reprojection error (px).

    Returns
    -------
    dict[str, str]
    """
    # scene3D.io.colmap imports this module (its writer shares write_text_files and
    # colmap_image_name), so the old writer cannot call the new one: it warns instead.
    warnings.warn(COLMAP_TEXT_FILES_DEPRECATION, DeprecationWarning, stacklevel=2)
    from ..geometry.conventions import quaternion_from_rotation

    fx, fy, cx, cy = K[0, 0], K[1, 1], K[0, 2] + 0.5, K[1, 2] + 0.5
    cameras = ("# Camera list with one line of data per camera:\n"
               "#   CAMERA_ID, MODEL, WIDTH, HEIGHT, PARAMS[]\n"
               f"1 PINHOLE {image_size[0]} {image_size[1]} {fx:.10g} {fy:.10g} "
               f"{cx:.10g} {cy:.10g}\n")
    # Index of each observation within its image's list of 2D points.
    point2d_index = np.zeros(len(obs_view), dtype=int)
    image_lines = ["# Image list with two lines of data per image:",
                   "#   IMAGE_ID, QW, QX, QY, QZ, TX, TY, TZ, CAMERA_ID, NAME",
                   "#   POINTS2D[] as (X, Y, POINT3D_ID)"]
    for v in np.nonzero(registered)[0]:
        mine = np.nonzero(obs_view == v)[0]
        point2d_index[mine] = np.arange(len(mine))
        q = quaternion_from_rotation(R[v])
        image_lines.append(f"{v + 1} " + " ".join(f"{x:.12g}" for x in (*q, *t[v]))
                           + f" 1 {colmap_image_name(names[v])}")
        image_lines.append(" ".join(f"{obs_xy[k, 0] + 0.5:.6f} {obs_xy[k, 1] + 0.5:.6f} "
                                    f"{obs_point[k] + 1}" for k in mine))
    point_lines = ["# 3D point list with one line of data per point:",
                   "#   POINT3D_ID, X, Y, Z, R, G, B, ERROR, TRACK[] as (IMAGE_ID, POINT2D_IDX)"]
    order = np.argsort(obs_point, kind="stable")
    starts = np.searchsorted(obs_point[order], np.arange(len(points3d) + 1))
    for p in range(len(points3d)):
        ks = order[starts[p]:starts[p + 1]]
        track = " ".join(f"{obs_view[k] + 1} {point2d_index[k]}" for k in ks)
        X, c = points3d[p], colors[p]
        point_lines.append(f"{p + 1} {X[0]:.10g} {X[1]:.10g} {X[2]:.10g} {c[0]} {c[1]} {c[2]} "
                           f"{errors_px[p]:.6f} {track}")
    return {"cameras.txt": cameras, "images.txt": "\n".join(image_lines) + "\n",
            "points3D.txt": "\n".join(point_lines) + "\n"}


def write_files(folder: str | os.PathLike, files: dict[str, bytes]) -> list[Path]:
    """Write several files into ``folder`` (created if needed), each atomically.

    Parameters
    ----------
    folder : str or os.PathLike
        Target folder.
    files : dict[str, bytes]
        Content by file name.

    Returns
    -------
    list of Path
    """
    folder = Path(folder)
    folder.mkdir(parents=True, exist_ok=True)
    return [atomic_write_bytes(folder / name, data) for name, data in files.items()]


def write_text_files(folder: str | os.PathLike, files: dict[str, str]) -> list[Path]:
    """Write several text files (UTF-8) into ``folder`` (created if needed), each
    atomically (:func:`write_files`).

    Parameters
    ----------
    folder : str or os.PathLike
        Target folder.
    files : dict[str, str]
        Text by file name.

    Returns
    -------
    list of Path
    """
    return write_files(folder, {name: text.encode("utf-8") for name, text in files.items()})
