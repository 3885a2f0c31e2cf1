"""COLMAP text models (``cameras.txt``, ``images.txt``, ``points3D.txt``) in and out.

A model read here is a :class:`ColmapModel` in scene3D's conventions, whatever wrote it
(COLMAP, pycolmap, hloc, scene3D):

- poses world-to-camera, ``x_cam = R @ X + t`` (COLMAP's ``cam_from_world``, the
  quaternion ``(qw, qx, qy, qz)`` made a rotation matrix);
- pixels in the OpenCV convention (integer coordinates at pixel centres): COLMAP puts
  pixel centres at ``+0.5``, so principal points and 2D points move by half a pixel on the
  way in and back on the way out;
- intrinsics as ``K`` ``(3, 3)`` and OpenCV distortion coefficients ``(k1, k2, p1, p2[,
  k3, k4, k5, k6])``; the camera models are those that OpenCV's model holds exactly:
  :data:`CAMERA_MODELS`.

The writers go through :mod:`scene3D.io.atomic` (atomic files). The files others add
beside the three (``rigs.txt``, ``frames.txt`` of COLMAP 3.12) are not read: each image is
its own camera pose.
"""

from __future__ import annotations

import os
from collections.abc import Iterator, Mapping, Sequence
from dataclasses import replace
from pathlib import Path

import numpy as np
from numpy.typing import ArrayLike

from ..geometry.camera import scale_intrinsics_resize, validate_distortion
from ..geometry.conventions import quaternion_from_rotation
from .atomic import write_text_files
from .colmap_model import (  # noqa: F401 - the model's types, from here as before
    CAMERA_MODELS,
    MODEL_FILES,
    ColmapCamera,
    ColmapFormatError,
    ColmapModel,
    ImageRecord,
    PointRecord,
    distorted_pixels,
    model_from_records,
    point2d_indices,
    project_points,
)


def model_for_photos(model: ColmapModel,
                     photo_size: tuple[int, int] | Mapping[int, tuple[int, int]],
                     dist: ArrayLike | Mapping[int, ArrayLike] | None = None) -> ColmapModel:
    """The model of undistorted images resized, as one of the photos they came from.

    Every camera of ``model`` (pinhole, of images that were resized from the photos and
    undistorted with their camera matrix kept) becomes the camera of photos of
    ``photo_size`` (width, height): intrinsics and observations scaled with pixel edges
    on pixel edges (:func:`scene3D.geometry.camera.scale_intrinsics`), and with ``dist``
    (OpenCV coefficients) the lens distortion put back into the camera (OPENCV or
    FULL_OPENCV) and the observations. Poses and points are unchanged; ``errors_px`` is
    recomputed at the photos' size.

    Parameters
    ----------
    model : ColmapModel
        A model with pinhole cameras of resized, undistorted images.
    photo_size : (int, int) or mapping of int to (int, int)
        The photos' ``(width, height)`` in px; by camera id for cameras of several sizes.
    dist : array_like, mapping of int to array_like, or None, default None
        The photos' OpenCV distortion coefficients (by camera id for several cameras);
        None for none.

    Returns
    -------
    ColmapModel


    Raises
    ------
    ValueError
        A camera of ``model`` with distortion, or another aspect ratio than ``photo_size``.
    """
    sizes = photo_size if isinstance(photo_size, Mapping) else dict.fromkeys(model.cameras,
                                                                               photo_size)
    lenses = dist if isinstance(dist, Mapping) else dict.fromkeys(model.cameras, dist)
    cameras = {}
    xy = model.obs_xy.copy()
    for cam_id, camera in model.cameras.items():
        photo_size, dist = tuple(sizes[cam_id]), validate_distortion(lenses[cam_id])
        if camera.dist.size:
            raise ValueError(f"camera {cam_id} of the model is {camera.model}: only "
                             "undistorted (pinhole) cameras are taken to the photos' size")
        w, h = camera.image_size
        if abs(photo_size[0] * h / (photo_size[1] * w) - 1) > 0.01:
            raise ValueError(f"camera {cam_id} is for {w}x{h} images, another aspect ratio "
                             f"than the photos' {photo_size[0]}x{photo_size[1]}")
        K = scale_intrinsics_resize(camera.K, camera.image_size, photo_size)
        cameras[cam_id] = ColmapCamera.from_opencv(K, dist, photo_size)
        mine = np.isin(model.obs_view, np.nonzero(model.camera_ids == cam_id)[0])
        normalized = (xy[mine] - camera.K[:2, 2]) / np.diag(camera.K)[:2]
        xy[mine] = distorted_pixels(normalized, K, dist)
    scaled = replace(model, cameras=cameras, obs_xy=xy)
    return replace(scaled, errors_px=scaled.point_errors_px())


# -- reading -----------------------------------------------------------------------------

def _data_lines(path: Path) -> list[tuple[int, str]]:
    """(line number, text) of the lines of ``path`` that are not comments; blank lines
    kept (an image without 2D points has a blank second line)."""
    try:
        text = path.read_text(encoding="utf-8")
    except FileNotFoundError:
        raise FileNotFoundError(2, "COLMAP model file not found", str(path)) from None
    return [(n, line.strip()) for n, line in enumerate(text.splitlines(), start=1)
            if not line.lstrip().startswith("#")]


def _numbers(path: Path, line: int, fields: list[str], what: str) -> list[float]:
    try:
        return [float(f) for f in fields]
    except ValueError:
        raise ColmapFormatError(f"'{path}' line {line}: {what} must be numbers, got "
                                f"{' '.join(fields)!r}") from None


def read_cameras_text(path: str | os.PathLike) -> dict[int, ColmapCamera]:
    """The cameras of a ``cameras.txt``, by id.

    Parameters
    ----------
    path : str or os.PathLike
        A COLMAP ``cameras.txt``.

    Returns
    -------
    dict[int, ColmapCamera]


    Raises
    ------
    ColmapFormatError
        A camera model other than :data:`CAMERA_MODELS` (the message names it and the
        file), a wrong number of parameters, a malformed line.
    """
    path = Path(path)
    cameras: dict[int, ColmapCamera] = {}
    for n, line in _data_lines(path):
        if not line:
            continue
        fields = line.split()
        if len(fields) < 4:
            raise ColmapFormatError(f"'{path}' line {n}: expected CAMERA_ID MODEL WIDTH "
                                    f"HEIGHT PARAMS[], got {line!r}")
        model = fields[1]
        if model not in CAMERA_MODELS:
            raise ColmapFormatError(f"'{path}' line {n}: camera model '{model}' is not "
                                    f"supported (supported: {', '.join(CAMERA_MODELS)})")
        cam_id, width, height = (int(v) for v in _numbers(path, n, [fields[0], *fields[2:4]],
                                                          "CAMERA_ID, WIDTH and HEIGHT"))
        params = _numbers(path, n, fields[4:], "the parameters")
        if len(params) != len(CAMERA_MODELS[model]):
            raise ColmapFormatError(f"'{path}' line {n}: camera model {model} has "
                                    f"{len(CAMERA_MODELS[model])} parameters "
                                    f"({', '.join(CAMERA_MODELS[model])}), got {len(params)}")
        cameras[cam_id] = ColmapCamera(model, width, height, tuple(params))
    return cameras


def _read_images(path: Path) -> list[ImageRecord]:
    """The images of an ``images.txt`` (:data:`~scene3D.io.colmap_model.ImageRecord`)."""
    lines = _data_lines(path)
    images = []
    k = 0
    while k < len(lines):
        n, header = lines[k]
        if not header:
            k += 1
            continue
        fields = header.split(maxsplit=9)
        if len(fields) < 10:
            raise ColmapFormatError(f"'{path}' line {n}: expected IMAGE_ID QW QX QY QZ TX TY "
                                    f"TZ CAMERA_ID NAME, got {header!r}")
        values = _numbers(path, n, fields[:9], "IMAGE_ID, the pose and CAMERA_ID")
        points_line = lines[k + 1][1] if k + 1 < len(lines) else ""
        pts = _numbers(path, n + 1, points_line.split(), "POINTS2D[]")
        if len(pts) % 3:
            raise ColmapFormatError(f"'{path}' line {n + 1}: POINTS2D[] must be (X, Y, "
                                    f"POINT3D_ID) triples, got {len(pts)} numbers")
        pts_arr = np.array(pts, dtype=np.float64).reshape(-1, 3)
        images.append((int(values[0]), tuple(values[1:8]), int(values[8]), fields[9],
                       pts_arr[:, :2]))
        k += 2
    return images


def _read_points(path: Path) -> Iterator[PointRecord]:
    """The points of a ``points3D.txt`` (:data:`~scene3D.io.colmap_model.PointRecord`)."""
    for n, line in _data_lines(path):
        if not line:
            continue
        fields = line.split()
        if len(fields) < 8 or (len(fields) - 8) % 2:
            raise ColmapFormatError(f"'{path}' line {n}: expected POINT3D_ID X Y Z R G B "
                                    f"ERROR TRACK[] as (IMAGE_ID, POINT2D_IDX), got {line!r}")
        values = _numbers(path, n, fields, "the fields")
        yield (f"'{path}' line {n}", int(values[0]), tuple(values[1:4]), tuple(values[4:7]),
               values[7], np.array(values[8:], dtype=np.int64).reshape(-1, 2))


def read_colmap_text(folder: str | os.PathLike) -> ColmapModel:
    """Read a COLMAP text model from ``folder`` (its ``cameras.txt``, ``images.txt`` and
    ``points3D.txt``) in scene3D's conventions (:class:`ColmapModel`).

    Observations come from the points' tracks, image by image in the order of their 2D
    points; 2D points that belong to no 3D point are not kept. :func:`read_colmap_model`
    reads a folder with either form.

    Parameters
    ----------
    folder : str or os.PathLike
        Folder holding ``cameras.txt``, ``images.txt`` and ``points3D.txt``.

    Returns
    -------
    ColmapModel
        World-to-camera poses (``x_cam = R X + t``) and OpenCV pixels (COLMAP's half-pixel
        offset removed).


    Raises
    ------
    FileNotFoundError
        ``folder`` or one of the three files is missing (the error names the file).
    ColmapFormatError
        An unsupported camera model (the message names the model and the file), a
        malformed line, an image of an unknown camera, a track naming an unknown image or
        2D point.
    """
    folder = Path(folder)
    if not folder.is_dir():
        raise FileNotFoundError(2, "COLMAP model folder not found", str(folder))
    cameras = read_cameras_text(folder / "cameras.txt")
    images = _read_images(folder / "images.txt")
    points = list(_read_points(folder / "points3D.txt"))
    return model_from_records(cameras, images, points, str(folder / "images.txt"))


def read_colmap_model(folder: str | os.PathLike) -> ColmapModel:
    """Read the COLMAP model in ``folder``, binary or text, as COLMAP chooses: the binary
    files when all three (``cameras.bin``, ``images.bin``, ``points3D.bin``) are there
    (:func:`scene3D.io.colmap_binary.read_colmap_binary`), else the text ones
    (:func:`read_colmap_text`).

    Parameters
    ----------
    folder : str or os.PathLike
        A COLMAP model folder (``sparse/0`` of a COLMAP project).

    Returns
    -------
    ColmapModel
        In scene3D's conventions, whichever form was read.


    Raises
    ------
    FileNotFoundError
        ``folder`` is missing, or holds neither form complete (the error names the
        first text file missing).
    ColmapFormatError
        As the reader of the form found says.
    """
    from .colmap_binary import BINARY_FILES, read_colmap_binary

    folder = Path(folder)
    if all((folder / name).is_file() for name in BINARY_FILES):
        return read_colmap_binary(folder)
    return read_colmap_text(folder)


def find_model_folder(path: str | os.PathLike) -> Path | None:
    """The folder of the COLMAP model in ``path``: ``path`` itself when it holds a whole
    model (the three text files or the three binary ones), else its ``colmap/`` (a
    ``reconstruct-views`` output folder) when that does; None when neither does.

    Parameters
    ----------
    path : str or os.PathLike
        A model folder, or a folder with a model in ``colmap/``.

    Returns
    -------
    Path or None
    """
    from .colmap_binary import BINARY_FILES

    path = Path(path)
    for folder in (path, path / "colmap"):  # model_files.COLMAP_FOLDER, which imports us
        if any(all((folder / name).is_file() for name in files)
               for files in (BINARY_FILES, MODEL_FILES)):
            return folder
    return None


# -- writing -----------------------------------------------------------------------------

def colmap_text(model: ColmapModel) -> dict[str, str]:
    """``model`` as the three files of a COLMAP text model (name -> text), every number
    to full precision (a model read back is the same).

    Parameters
    ----------
    model : ColmapModel
        The model to write.

    Returns
    -------
    dict[str, str]
        ``cameras.txt``, ``images.txt`` and ``points3D.txt`` by name.
    """
    from .export import colmap_image_name

    def num(x: float) -> str:
        return f"{float(x):.17g}"

    cameras = ["# Camera list with one line of data per camera:",
               "#   CAMERA_ID, MODEL, WIDTH, HEIGHT, PARAMS[]",
               f"# Number of cameras: {len(model.cameras)}"]
    for cam_id in sorted(model.cameras):
        c = model.cameras[cam_id]
        cameras.append(f"{cam_id} {c.model} {c.width} {c.height} "
                       + " ".join(num(p) for p in c.params))
    point2d_index = point2d_indices(model)
    images = ["# Image list with two lines of data per image:",
              "#   IMAGE_ID, QW, QX, QY, QZ, TX, TY, TZ, CAMERA_ID, NAME",
              "#   POINTS2D[] as (X, Y, POINT3D_ID)",
              f"# Number of images: {len(model.names)}"]
    for v, name in enumerate(model.names):
        mine = np.nonzero(model.obs_view == v)[0]
        q = quaternion_from_rotation(model.R[v])
        images.append(f"{model.image_ids[v]} " + " ".join(num(x) for x in (*q, *model.t[v]))
                      + f" {model.camera_ids[v]} {colmap_image_name(name)}")
        images.append(" ".join(f"{num(model.obs_xy[k, 0] + 0.5)} "
                               f"{num(model.obs_xy[k, 1] + 0.5)} "
                               f"{model.point_ids[model.obs_point[k]]}" for k in mine))
    points = ["# 3D point list with one line of data per point:",
              "#   POINT3D_ID, X, Y, Z, R, G, B, ERROR, TRACK[] as (IMAGE_ID, POINT2D_IDX)",
              f"# Number of points: {len(model.points3d)}"]
    order = np.argsort(model.obs_point, kind="stable")
    starts = np.searchsorted(model.obs_point[order], np.arange(len(model.points3d) + 1))
    for p in range(len(model.points3d)):
        ks = order[starts[p]:starts[p + 1]]
        X, c = model.points3d[p], model.colors[p]
        track = " ".join(f"{model.image_ids[model.obs_view[k]]} {point2d_index[k]}"
                         for k in ks)
        points.append(f"{model.point_ids[p]} {num(X[0])} {num(X[1])} {num(X[2])} "
                      f"{c[0]} {c[1]} {c[2]} {num(model.errors_px[p])} {track}".rstrip())
    return {"cameras.txt": "\n".join(cameras) + "\n", "images.txt": "\n".join(images) + "\n",
            "points3D.txt": "\n".join(points) + "\n"}


def cameras_json(model: ColmapModel) -> dict[str, dict]:
    """Each image's camera as JSON-ready values, by image name: world-to-camera ``R``
    ``(3, 3)`` and ``t`` ``(3,)``, the centre ``(3,)``, ``K`` ``(3, 3)`` (OpenCV pixels),
    the OpenCV ``distortion`` coefficients, ``image_size`` ``[width, height]`` and COLMAP's
    ``camera_model``.

    Parameters
    ----------
    model : ColmapModel
        The model.

    Returns
    -------
    dict[str, dict]
    """
    centers = model.centers
    out = {}
    for v, name in enumerate(model.names):
        camera = model.camera(v)
        out[name] = {"R": model.R[v], "t": model.t[v], "center": centers[v], "K": camera.K,
                     "distortion": camera.dist, "image_size": list(camera.image_size),
                     "camera_model": camera.model}
    return out


def write_colmap_text(folder: str | os.PathLike, model: ColmapModel) -> list[Path]:
    """Write ``model`` as a COLMAP text model into ``folder`` (created if needed), each
    file atomically; returns the paths written.

    Parameters
    ----------
    folder : str or os.PathLike
        Target folder.
    model : ColmapModel
        The model to write.

    Returns
    -------
    list of Path
    """
    return write_text_files(folder, colmap_text(model))


def colmap_model_from_views(names: list[str] | tuple[str, ...], K: ArrayLike,
                            image_size: tuple[int, int] | Sequence[tuple[int, int]],
                            registered: ArrayLike,
                            R: ArrayLike, t: ArrayLike, points3d: ArrayLike,
                            colors: ArrayLike, obs_view: ArrayLike, obs_point: ArrayLike,
                            obs_xy: ArrayLike, view_camera: ArrayLike | None = None
                            ) -> ColmapModel:
    """A model with one camera (PINHOLE ``K`` for images of ``image_size``; one per camera
    with ``view_camera``) of the views that
    are ``registered`` ``(V,)`` among ``names``, image ids ``view + 1``, point ids
    ``point + 1``; poses ``R`` ``(V, 3, 3)``, ``t`` ``(V, 3)`` world-to-camera; the
    observations ``obs_view`` (indices into ``names``), ``obs_point``, ``obs_xy``
    ``(O, 2)`` OpenCV pixels.

    Parameters
    ----------
    names : list or tuple of str
        The views' image names, ``V`` of them.
    K : (3, 3) array_like
        Intrinsics shared by the views (OpenCV pixels).
    image_size : (int, int)
        ``(width, height)`` in px.
    registered : (V,) bool array_like
        Views in the model.
    R : (V, 3, 3) array_like
        World-to-camera rotations.
    t : (V, 3) array_like
        World-to-camera translations.
    points3d : (P, 3) array_like
        World points.
    colors : (P, 3) uint8 array_like
        RGB colours.
    obs_view, obs_point : (O,) int array_like
        View and point of each observation.
    obs_xy : (O, 2) array_like
        Observed pixels (OpenCV convention).
    view_camera : (V,) int array_like or None, default None
        Views of several cameras: the camera of each view; ``K`` is then ``(C, 3, 3)``
        and ``image_size`` one size per camera, camera ids ``camera + 1`` (those of the
        registered views).

    Returns
    -------
    ColmapModel
    """
    registered = np.asarray(registered, dtype=bool)
    views = np.nonzero(registered)[0]
    index = np.full(len(registered), -1)
    index[views] = np.arange(len(views))
    obs_view = np.asarray(obs_view, dtype=np.int64)
    keep = registered[obs_view]
    points3d = np.asarray(points3d, dtype=np.float64).reshape(-1, 3)
    if view_camera is None:
        cameras = {1: ColmapCamera.from_opencv(K, None, image_size)}
        camera_ids = np.ones(len(views), dtype=np.int64)
    else:
        camera_ids = np.asarray(view_camera, dtype=np.int64)[views] + 1
        Ks = np.asarray(K, np.float64).reshape(-1, 3, 3)
        cameras = {int(c): ColmapCamera.from_opencv(Ks[c - 1], None, tuple(image_size[c - 1]))
                   for c in np.unique(camera_ids)}
    model = ColmapModel(
        cameras=cameras, image_ids=views.astype(np.int64) + 1,
        names=tuple(names[v] for v in views), camera_ids=camera_ids,
        R=np.asarray(R, np.float64)[views].reshape(-1, 3, 3),
        t=np.asarray(t, np.float64)[views].reshape(-1, 3),
        point_ids=np.arange(1, len(points3d) + 1, dtype=np.int64), points3d=points3d,
        colors=np.asarray(colors, dtype=np.uint8).reshape(-1, 3),
        errors_px=np.zeros(len(points3d)), obs_view=index[obs_view[keep]],
        obs_point=np.asarray(obs_point, dtype=np.int64)[keep],
        obs_xy=np.asarray(obs_xy, dtype=np.float64).reshape(-1, 2)[keep])
    return replace(model, errors_px=model.point_errors_px())
