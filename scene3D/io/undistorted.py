"""Undistorted copies of a model's images, and the pinhole model that describes them.

NeRF and Gaussian-splatting trainers model a pinhole camera best (several ignore the
distortion terms of ``transforms.json``, or only approximate them). For them, each image
of a model is written undistorted (:func:`write_undistorted_images`): at the size its
camera says, with the camera's own ``K`` kept as the camera matrix (OpenCV's
``undistort``), so that a point the distorted camera projects to ``p`` in the image lies
at the pinhole projection ``K [R | t] X`` in the copy. Pixels the lens did not see
(outside the photo once undistorted: the corners of a barrel lens) are black. The model
that goes with the copies (:func:`pinhole_model`) has PINHOLE cameras of the same ``K``
and size, and its observations undistorted likewise; poses and points are unchanged.

Copies are PNG (lossless), named as the image with ``.png`` for its suffix
(:func:`undistorted_image_name`: ``0004.jpg`` -> ``0004.png``). Images are BGR ``uint8``
as OpenCV reads them.
"""

from __future__ import annotations

import os
from collections.abc import Mapping
from dataclasses import replace
from pathlib import Path

import cv2
import numpy as np

from ..geometry.camera import undistort_image
from .colmap_model import ColmapCamera, ColmapModel
from .export import write_png
from .images import IMAGE_SUFFIXES, load_bgr, read_image_size

#: Where the commands put the undistorted copies, in their output folder.
UNDISTORTED_FOLDER = "undistorted"

#: An image's path, or the image itself ``(H, W[, 3]) uint8``.
ImageOrPath = str | os.PathLike | np.ndarray


def model_image(images: str | os.PathLike | Mapping[str, ImageOrPath], name: str
                ) -> ImageOrPath:
    """Image ``name`` of a model: ``images / name`` for a folder, ``images[name]`` for a
    mapping (a path, or for :func:`write_undistorted_images` an array too).

    Parameters
    ----------
    images : path or mapping of str to path or ndarray
        The images' folder, or each image (or its path) by its name in the model.
    name : str
        The name in the model.

    Returns
    -------
    path or ndarray


    Raises
    ------
    ValueError
        A mapping without ``name``.
    """
    if isinstance(images, Mapping):
        try:
            return images[name]
        except KeyError:
            raise ValueError(f"`images` has no path for the model's image '{name}'") from None
    return Path(images) / name


def require_camera_size(name: str, size: tuple[int, int] | None,
                        camera: ColmapCamera) -> None:
    """Raise ``ValueError`` when image ``name``, of ``size`` (None: not an image), is not
    of the size ``camera`` is for.

    Parameters
    ----------
    name : str
        The image's name in the model.
    size : (int, int) or None
        ``(width, height)`` of the image.
    camera : ColmapCamera
        Its camera.
    """
    if size != camera.image_size:
        shown = "not an image" if size is None else f"{size[0]}x{size[1]}"
        raise ValueError(f"image '{name}' is {shown}, its camera is for "
                         f"{camera.width}x{camera.height} images")


def check_model_images(model: ColmapModel,
                       images: str | os.PathLike | Mapping[str, ImageOrPath]) -> None:
    """Check that ``images`` gives every image of ``model`` at the size its camera says
    (a file's size from its header, not decoded), before anything is written for them.

    Parameters
    ----------
    model : ColmapModel
        The model.
    images : path or mapping of str to path or ndarray
        The images' folder, or each image (or its path) by its name in the model
        (:func:`model_image`).

    Raises
    ------
    FileNotFoundError
        An image file that is missing (the error names it).
    ValueError
        An image ``images`` does not give, one that cannot be read, or one of another size
        than its camera's.
    """
    for v, name in enumerate(model.names):
        source = model_image(images, name)
        if isinstance(source, np.ndarray):
            size = (source.shape[1], source.shape[0]) if source.ndim >= 2 else None
        else:
            if not Path(source).is_file():
                raise FileNotFoundError(2, f"no file for the model's image '{name}'",
                                        str(source))
            size = read_image_size(source)
        require_camera_size(name, size, model.camera(v))


def undistorted_image_name(name: str) -> str:
    """The file name of the undistorted copy of image ``name``: ``.png`` for its image
    suffix (``a.jpg`` -> ``a.png``), or added to a name without one (a video frame's
    ``t001.20s`` -> ``t001.20s.png``).

    Parameters
    ----------
    name : str
        The image's name in the model (a relative path).

    Returns
    -------
    str
    """
    path = Path(name)
    if path.suffix.lower() in IMAGE_SUFFIXES:
        return path.with_suffix(".png").as_posix()
    return f"{path.as_posix()}.png"


def pinhole_model(model: ColmapModel) -> ColmapModel:
    """``model`` as its images undistorted with :func:`write_undistorted_images` show it.

    Each camera becomes PINHOLE with its ``K`` and size; each observation moves to where
    the undistorted copy has it (``cv2.undistortPoints`` back onto ``K``); the
    ``errors_px`` are recomputed. Poses, points and tracks are unchanged.

    Parameters
    ----------
    model : ColmapModel

    Returns
    -------
    ColmapModel
    """
    xy = model.obs_xy.copy()
    cameras = {}
    criteria = (cv2.TERM_CRITERIA_COUNT | cv2.TERM_CRITERIA_EPS, 50, 1e-12)
    for cam_id, camera in model.cameras.items():
        cameras[cam_id] = ColmapCamera.from_opencv(camera.K, None, camera.image_size)
        mine = np.isin(model.obs_view, np.nonzero(model.camera_ids == cam_id)[0])
        if camera.dist.size and np.any(camera.dist) and mine.any():
            xy[mine] = cv2.undistortPoints(
                xy[mine].reshape(-1, 1, 2), camera.K, camera.dist, None, None, camera.K,
                criteria).reshape(-1, 2)
    pinhole = replace(model, cameras=cameras, obs_xy=xy)
    return replace(pinhole, errors_px=pinhole.point_errors_px())


def write_undistorted_images(folder: str | os.PathLike, model: ColmapModel,
                             images: str | os.PathLike | Mapping[str, ImageOrPath]
                             ) -> tuple[ColmapModel, dict[str, Path]]:
    """Write each image of ``model`` undistorted into ``folder`` (created if needed; PNG,
    each atomically), and return the model of the copies and their paths.

    Parameters
    ----------
    folder : str or os.PathLike
        Where the copies go (``folder / undistorted_image_name(name)``).
    model : ColmapModel
        The model; its cameras must be those of the images as given (their size).
    images : path or mapping of str to path or ndarray
        The images' folder, or each image (a path, or a BGR or grey ``uint8`` array) by
        its name in the model (:func:`model_image`).

    Returns
    -------
    ColmapModel
        :func:`pinhole_model` of ``model``, its names those of the copies.
    dict[str, Path]
        The copy of each image, by the copy's name (as ``nerfstudio_transforms`` takes
        them).


    Raises
    ------
    ValueError
        An image of another size than its camera's, two images whose copies would share
        a name (``a.jpg`` and ``a.png``), or an image ``images`` does not give.
    FileNotFoundError, ValueError
        An image file that is missing or cannot be read.
    """
    folder = Path(folder)
    names = [undistorted_image_name(name) for name in model.names]
    first: dict[str, str] = {}
    for name, copy in zip(model.names, names):
        other = first.setdefault(copy, name)
        if other != name:
            raise ValueError(f"the images '{other}' and '{name}' would both be undistorted "
                             f"as '{copy}': rename one")
    written: dict[str, Path] = {}
    for v, name in enumerate(model.names):
        camera = model.camera(v)
        source = model_image(images, name)
        image = load_bgr(source, name=name)
        require_camera_size(name, (image.shape[1], image.shape[0]), camera)
        path = folder / names[v]
        path.parent.mkdir(parents=True, exist_ok=True)
        written[names[v]] = write_png(path, undistort_image(image, camera.K, camera.dist))
    return replace(pinhole_model(model), names=tuple(names)), written
