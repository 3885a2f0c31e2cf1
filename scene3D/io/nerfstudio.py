"""nerfstudio's ``transforms.json``: cameras for NeRF and Gaussian-splatting trainers.

The format (https://docs.nerf.studio/quickstart/data_conventions.html, which instant-ngp
and gsplat's loaders follow too):

- intrinsics ``camera_model`` (``"OPENCV"``: ``fl_x, fl_y, cx, cy`` with radial ``k1, k2``
  and tangential ``p1, p2``), ``w`` and ``h`` at the top of the file when every image has
  the same camera, else in each frame;
- pixels with pixel centres at ``+0.5`` (a ray for pixel (0, 0) goes through its
  centre), as COLMAP: ``cx`` is OpenCV's ``cx + 0.5``;
- each frame's ``transform_matrix`` ``(4, 4)`` is camera-to-world in the OpenGL camera
  axes (x right, y up, z back: the camera looks along -z), that is OpenCV's
  camera-to-world ``[R^T | C]`` with its y and z columns negated;
- ``file_path`` is relative to the folder of the JSON file.

The world frame is the model's, unchanged (nerfstudio re-orients and re-centres it when
it loads the file); ``ply_file_path`` names the points, in that frame, for splatting
trainers that start from them.
"""

from __future__ import annotations

import os
from collections.abc import Mapping
from pathlib import Path

import numpy as np

from ..geometry.conventions import FloatArray
from .atomic import all_or_nothing
from .colmap import ColmapCamera, ColmapModel
from .export import write_json
from .ply import write_ply
from .undistorted import (
    UNDISTORTED_FOLDER,
    check_model_images,
    model_image,
    undistorted_image_name,
    write_undistorted_images,
)

#: OpenCV camera axes (x right, y down, z forward) to OpenGL's (x right, y up, z back).
OPENGL_FROM_OPENCV = np.diag([1.0, -1.0, -1.0])

#: The file's name, and the point cloud's as :func:`export_nerfstudio` writes it beside
#: (the name nerfstudio's own ``ns-process-data`` gives it).
NERFSTUDIO_FILE = "transforms.json"
NERFSTUDIO_POINTS_FILE = "sparse_pc.ply"

#: The intrinsics keys of a frame or of the file's top.
INTRINSICS_KEYS = ("camera_model", "fl_x", "fl_y", "cx", "cy", "w", "h", "k1", "k2", "k3",
                   "p1", "p2")


class NerfstudioCameraError(ValueError):
    """A camera that nerfstudio's OPENCV model cannot hold (rational distortion ``k4``..``k6``);
    ``camera_model`` is COLMAP's name of it. Its images undistorted (PINHOLE) can be written."""

    def __init__(self, message: str, camera_model: str) -> None:
        super().__init__(message)
        self.camera_model = camera_model


def camera_to_world_opengl(R: FloatArray, t: FloatArray) -> FloatArray:
    """The ``(4, 4)`` camera-to-world matrix in OpenGL camera axes of a world-to-camera
    pose ``x_cam = R X + t`` (OpenCV axes): ``[[R^T diag(1, -1, -1), C], [0, 1]]`` with the
    centre ``C = -R^T t``.

    Parameters
    ----------
    R, t : (3, 3), (3,) array_like
        World-to-camera pose, ``x_cam = R X + t`` (OpenCV axes).

    Returns
    -------
    (4, 4) float64 ndarray
    """
    R = np.asarray(R, dtype=np.float64)
    t = np.asarray(t, dtype=np.float64)
    M = np.eye(4)
    M[:3, :3] = R.T @ OPENGL_FROM_OPENCV
    M[:3, 3] = -R.T @ t
    return M


def nerfstudio_intrinsics(camera: ColmapCamera) -> dict[str, float | int | str]:
    """A camera as nerfstudio's intrinsics keys (``camera_model`` ``"OPENCV"``).

    Parameters
    ----------
    camera : ColmapCamera
        The camera (OpenCV pixels; nerfstudio's principal point is shifted by half a pixel).

    Returns
    -------
    dict[str, float or int or str]


    Raises
    ------
    NerfstudioCameraError
        A FULL_OPENCV camera with ``k4``..``k6`` (rational) terms, which nerfstudio's
        perspective model does not have.
    """
    K, dist = camera.K, np.zeros(8)
    dist[:camera.dist.size] = camera.dist
    if np.any(dist[5:] != 0):
        raise NerfstudioCameraError(
            f"a {camera.model} camera with k4..k6 (rational distortion) cannot be written "
            "for nerfstudio, whose OPENCV model has k1, k2, k3, p1, p2", camera.model)
    out: dict[str, float | int | str] = {
        "camera_model": "OPENCV", "fl_x": float(K[0, 0]), "fl_y": float(K[1, 1]),
        "cx": float(K[0, 2] + 0.5), "cy": float(K[1, 2] + 0.5),
        "w": camera.width, "h": camera.height,
        "k1": float(dist[0]), "k2": float(dist[1]), "p1": float(dist[2]), "p2": float(dist[3])}
    if dist[4] != 0:
        out["k3"] = float(dist[4])
    return out


def _image_path(images: str | os.PathLike | Mapping[str, str | os.PathLike], name: str
                ) -> Path:
    source = model_image(images, name)
    if isinstance(source, np.ndarray):
        raise ValueError(f"`images` gives the model's image '{name}' as an array: "
                         "transforms.json names files (write_undistorted_images writes them)")
    return Path(source)


def nerfstudio_transforms(model: ColmapModel,
                          images: str | os.PathLike | Mapping[str, str | os.PathLike],
                          json_folder: str | os.PathLike,
                          ply_file: str | os.PathLike | None = None) -> dict:
    """The content of a ``transforms.json`` for ``model``, to be written in ``json_folder``.

    Parameters
    ----------
    model : ColmapModel
        Cameras and world-to-camera poses (:func:`scene3D.io.colmap.read_colmap_text`,
        :meth:`scene3D.multiview.MultiViewReconstruction.colmap_model`); its cameras
        must be those of the images as stored.
    images : path or mapping
        The folder of the images (each at ``images / name``), or each image's path by
        its name in the model.
    json_folder : path
        Where the file goes: every ``file_path`` (and ``ply_file_path``) is relative to it.
    ply_file : path, optional
        A point cloud in the model's world frame (``points.ply``), named by
        ``ply_file_path``.

    Returns
    -------
    dict
        One camera: its intrinsics at the top; several: in each frame.
    """
    folder = Path(json_folder)

    def relative(path: str | os.PathLike) -> str:
        return Path(os.path.relpath(Path(path).absolute(), folder.absolute())).as_posix()

    cameras = {int(c) for c in model.camera_ids}
    shared = len(cameras) == 1
    out: dict = {}
    if shared:
        out.update(nerfstudio_intrinsics(model.cameras[cameras.pop()]))
    frames = []
    for v, name in enumerate(model.names):
        frame: dict = {"file_path": relative(_image_path(images, name)),
                       "transform_matrix": camera_to_world_opengl(model.R[v], model.t[v])}
        if not shared:
            frame.update(nerfstudio_intrinsics(model.camera(v)))
        frames.append(frame)
    out["frames"] = frames
    if ply_file is not None:
        out["ply_file_path"] = relative(ply_file)
    return out


def write_nerfstudio(path: str | os.PathLike, model: ColmapModel,
                     images: str | os.PathLike | Mapping[str, str | os.PathLike],
                     ply_file: str | os.PathLike | None = None) -> Path:
    """Write ``model`` as nerfstudio's ``transforms.json`` at ``path`` (atomically):
    :func:`nerfstudio_transforms` with the paths relative to ``path``'s folder.

    Parameters
    ----------
    path : str or os.PathLike
        Target ``transforms.json``.
    model : ColmapModel
        The model.
    images : path or mapping of str to path
        The images' folder, or each image's path by name.
    ply_file : str, os.PathLike or None, default None
        The point cloud to name in the file; None for none.

    Returns
    -------
    Path
    """
    path = Path(path)
    return write_json(path, nerfstudio_transforms(model, images, path.parent, ply_file))


def nerfstudio_export_files(folder: str | os.PathLike, model: ColmapModel,
                            undistort: bool = False,
                            points_file: str | None = NERFSTUDIO_POINTS_FILE,
                            undistorted_folder: str | os.PathLike | None = None) -> list[Path]:
    """The files :func:`export_nerfstudio` writes with these arguments, written or not
    (for a caller that checks what they would replace first).

    Parameters
    ----------
    folder, model, undistort, points_file, undistorted_folder
        As :func:`export_nerfstudio` takes them.

    Returns
    -------
    list of Path
        ``transforms.json``, the point cloud, then the undistorted copies.
    """
    folder = Path(folder)
    files = [folder / NERFSTUDIO_FILE]
    if points_file is not None:
        files.append(folder / points_file)
    if undistort:
        copies = _copies_folder(folder, undistorted_folder)
        files += [copies / undistorted_image_name(name) for name in model.names]
    return files


def _copies_folder(folder: Path, undistorted_folder: str | os.PathLike | None) -> Path:
    """Where the undistorted copies go: ``undistorted_folder``, by default
    ``folder / UNDISTORTED_FOLDER``."""
    return Path(undistorted_folder) if undistorted_folder is not None \
        else folder / UNDISTORTED_FOLDER


def export_nerfstudio(folder: str | os.PathLike, model: ColmapModel,
                      images: str | os.PathLike | Mapping[str, str | os.PathLike | np.ndarray],
                      undistort: bool = False,
                      points_file: str | None = NERFSTUDIO_POINTS_FILE,
                      undistorted_folder: str | os.PathLike | None = None) -> list[Path]:
    """Write ``model`` for nerfstudio (and instant-ngp, gsplat) into ``folder`` (created if
    needed), all files or none: ``transforms.json`` (:func:`write_nerfstudio`), the points
    as ``points_file`` (binary PLY, named by ``ply_file_path``) and, with ``undistort``,
    each image undistorted (:func:`scene3D.io.undistorted.write_undistorted_images`) with
    the PINHOLE cameras of the copies in ``transforms.json``. The images are checked
    first (:func:`scene3D.io.undistorted.check_model_images`): when one is missing or of
    another size than its camera, nothing is written.

    Parameters
    ----------
    folder : str or os.PathLike
        Where ``transforms.json`` and the points go.
    model : ColmapModel
        The model (:func:`scene3D.io.colmap.read_colmap_model`,
        :meth:`scene3D.multiview.MultiViewReconstruction.colmap_model`); its cameras must
        be those of the images as stored.
    images : path or mapping of str to path or ndarray
        The images' folder, or each image by its name in the model; arrays (BGR
        ``uint8``) only with ``undistort`` (``transforms.json`` names files).
    undistort : bool, default False
        Write undistorted copies (PNG) and name those.
    points_file : str or None, default NERFSTUDIO_POINTS_FILE
        The point cloud's name in ``folder``; None for no point cloud.
    undistorted_folder : str, os.PathLike or None, default None
        Where the copies go; None for ``folder / "undistorted"``.

    Returns
    -------
    list of Path
        The files written, in the order of :func:`nerfstudio_export_files`.


    Raises
    ------
    FileNotFoundError, ValueError
        An image missing, unreadable or of another size than its camera; without
        ``undistort``, an image given as an array.
    NerfstudioCameraError
        Without ``undistort``, a camera nerfstudio's OPENCV model cannot hold (rational
        distortion; ``undistort`` writes its images as PINHOLE).
    """
    folder = Path(folder)
    check_model_images(model, images)
    json_file = folder / NERFSTUDIO_FILE
    ply_file = None if points_file is None else folder / points_file
    if not undistort:  # its errors (an array, a rational lens) before any file is written
        transforms = nerfstudio_transforms(model, images, folder, ply_file)
    with all_or_nothing():
        folder.mkdir(parents=True, exist_ok=True)
        written: list[Path] = []
        if ply_file is not None:
            written.append(write_ply(ply_file, model.points3d, model.colors))
        if undistort:
            model, paths = write_undistorted_images(
                _copies_folder(folder, undistorted_folder), model, images)
            transforms = nerfstudio_transforms(model, paths, folder, ply_file)
        written.insert(0, write_json(json_file, transforms))
        if undistort:
            written += paths.values()
    return written
