"""Writing results: JSON summaries, figures, PNG images (and the first COLMAP writer).

Every writer goes through :mod:`scene3D.io.atomic` (a file complete or not there, the
files of an :func:`all_or_nothing` block all or none). The atomic writes and the PLY
files (:mod:`scene3D.io.ply`) lived here first: their names are importable from here as
before.
"""

from __future__ import annotations

import io
import json
import math
import os
import warnings
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from .atomic import (  # noqa: F401 - importable from here as before
    all_or_nothing,
    atomic_write_bytes,
    atomic_write_pieces,
    check_target,
    place_file,
    write_files,
    write_text_files,
    written_bytes,
)
from .ply import ply_bytes, read_ply, read_ply_normals, write_ply  # noqa: F401

if TYPE_CHECKING:
    from matplotlib.figure import Figure


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
    # scene3D.io.colmap imports this module (its writer shares colmap_image_name), so
    # the old writer cannot call the new one: it warns instead.
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
