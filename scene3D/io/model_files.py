"""The files of one reconstructed model, as the commands write them.

In a model's folder: the points (binary PLY, RGB), ``cameras.json`` (each image's
world-to-camera ``R``, ``t``, centre, ``K``, distortion and size:
:func:`scene3D.io.colmap.cameras_json`), ``colmap/`` (a COLMAP text model:
:func:`scene3D.io.colmap.write_colmap_text`) and, given the images' paths, nerfstudio's
``transforms.json`` (:func:`scene3D.io.nerfstudio.write_nerfstudio`). The results'
``save`` methods (:meth:`scene3D.multiview.MultiViewReconstruction.save`,
:meth:`scene3D.twoview.TwoViewReconstruction.save`,
:meth:`scene3D.SceneReconstruction3D.save`) write through :func:`save_model`.
"""

from __future__ import annotations

import os
from collections.abc import Mapping
from pathlib import Path

from .colmap import ColmapModel, cameras_json, write_colmap_text
from .export import write_json, write_ply
from .nerfstudio import NERFSTUDIO_FILE, export_nerfstudio  # noqa: F401 - as before

#: The names of the files in a model's folder.
CAMERAS_FILE = "cameras.json"
COLMAP_FOLDER = "colmap"


def save_model(folder: str | os.PathLike, model: ColmapModel,
               images: str | os.PathLike | Mapping[str, str | os.PathLike] | None = None,
               points_file: str = "points.ply", undistort: bool = False,
               undistorted_folder: str | os.PathLike | None = None) -> list[Path]:
    """Write ``model``'s files into ``folder`` (created if needed), each atomically: the
    points as ``points_file``, ``cameras.json``, ``colmap/cameras.txt``, ``images.txt``,
    ``points3D.txt`` and, when ``images`` (their folder, or each image's path by its name
    in the model) is given, ``transforms.json`` (with ``undistort``, of the images
    undistorted into ``undistorted_folder``:
    :func:`scene3D.io.nerfstudio.export_nerfstudio`). Returns the paths written.

    Parameters
    ----------
    folder : str or os.PathLike
        Target folder.
    model : ColmapModel
        The model.
    images : path, mapping of str to path, or None, default None
        The images' folder, or each image's path by name; None for no ``transforms.json``.
    points_file : str, default "points.ply"
        Name of the point cloud.
    undistort : bool, default False
        With ``images``: write them undistorted (PNG) and name those in
        ``transforms.json``, with PINHOLE cameras.
    undistorted_folder : str, os.PathLike or None, default None
        Where the copies go; None for ``folder / "undistorted"``.

    Returns
    -------
    list of Path
        The point cloud, ``cameras.json``, the COLMAP files, then ``transforms.json``
        and the undistorted copies.


    Raises
    ------
    ValueError
        ``undistort`` without ``images``.
    FileNotFoundError, ValueError
        As :func:`scene3D.io.nerfstudio.export_nerfstudio` (an image missing or of
        another size than its camera): nothing is written then.
    """
    if images is None and undistort:
        raise ValueError("`undistort` needs `images`: the images to undistort")
    folder = Path(folder)
    nerfstudio: list[Path] = []
    if images is not None:  # first: it checks the images, and writes the cloud
        nerfstudio = export_nerfstudio(folder, model, images, undistort, points_file,
                                       undistorted_folder)
        cloud = nerfstudio.pop(1)
    else:
        folder.mkdir(parents=True, exist_ok=True)
        cloud = write_ply(folder / points_file, model.points3d, model.colors)
    written = [cloud, write_json(folder / CAMERAS_FILE, cameras_json(model))]
    return written + write_colmap_text(folder / COLMAP_FOLDER, model) + nerfstudio
