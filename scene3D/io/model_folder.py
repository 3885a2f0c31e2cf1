"""The folder of a many-view model: its point cloud, cameras, COLMAP text model and figure.

One model of a :class:`scene3D.multiview.MultiViewReconstruction` is written into one
folder (``scene3d reconstruct-views`` writes the largest into its output folder and each
further model ``m`` into ``model-m/`` there, :func:`model_folder_name`):

- ``points.ply``: the points (binary PLY, RGB), in the model's world frame;
- ``cameras.json``: each registered view's world-to-camera pose ``R``, ``t``, centre,
  ``K``, distortion and image size, at the photos' size
  (:func:`scene3D.io.colmap.cameras_json`);
- ``colmap/cameras.txt``, ``colmap/images.txt``, ``colmap/points3D.txt``: a COLMAP text
  model of the photos as stored (:meth:`scene3D.multiview.MultiViewReconstruction.colmap_model`,
  :func:`scene3D.io.model_files.save_model`);
- ``cameras.png``: the cloud with the camera frusta (optional; matplotlib).

Each file is written atomically (:mod:`scene3D.io.export`). Frames as in
:mod:`scene3D.geometry`: ``x_cam = R X + t``, arbitrary scale.
"""

from __future__ import annotations

import os
from pathlib import Path
from typing import TYPE_CHECKING

from .export import save_figure
from .model_files import save_model

if TYPE_CHECKING:
    from ..multiview.models import MultiViewReconstruction, SfMModel

#: The files of a model in its folder, and its figure.
MODEL_FILES = ("points.ply", "cameras.json", "colmap/cameras.txt", "colmap/images.txt",
               "colmap/points3D.txt")
MODEL_FIGURE = "cameras.png"


def model_folder_name(m: int) -> str:
    """Where model ``m`` (0: the largest) goes, relative to the output folder.

    Parameters
    ----------
    m : int
        Index into ``MultiViewReconstruction.models``.

    Returns
    -------
    str
        ``"."`` for the largest model, ``"model-m"`` for the others.
    """
    return "." if m == 0 else f"model-{m}"


def write_model(folder: str | os.PathLike, recon: MultiViewReconstruction, model: SfMModel,
                figure: bool = True, created: list[Path] | None = None) -> list[Path]:
    """Write one model's files (:data:`MODEL_FILES`, and :data:`MODEL_FIGURE`) into ``folder``.

    Parameters
    ----------
    folder : path
        The model's folder; it and its ``colmap/`` subfolder are created when missing
        (its parent must exist).
    recon : MultiViewReconstruction
        The reconstruction the model belongs to (its view names, image size and ``K``).
    model : SfMModel
        One of ``recon.models``.
    figure : bool
        Also draw ``cameras.png`` (matplotlib).
    created : list of Path, optional
        The folders this call creates are appended to it (for a caller that removes
        them again when its run fails).

    Returns
    -------
    list of Path
        The files written, in the order of :data:`MODEL_FILES`, then the figure.
    """
    folder = Path(folder)
    for made in (folder, folder / "colmap"):
        if not made.exists():
            made.mkdir()
            if created is not None:
                created.append(made)
    # At the photos' size, with their distortion (MultiViewReconstruction.colmap_model).
    written = save_model(folder, recon.colmap_model(model), points_file=MODEL_FILES[0])
    if figure:
        from ..viz.plotting import plot_cameras_and_points

        fig = plot_cameras_and_points(model.points3d, model.colors, model.R, model.t,
                                      recon.model_K(model), recon.image_size)
        written.append(save_figure(fig, folder / MODEL_FIGURE))
    return written
