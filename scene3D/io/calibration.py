"""Reading and writing camera calibrations as OpenCV FileStorage (YAML or XML).

The file holds ``camera_matrix`` (3x3), ``distortion_coefficients`` (1xn),
``image_width`` and ``image_height``; ``calibrate.py`` adds ``rms_px``,
``per_view_errors``, the board description and the date. Any program with
``cv2.FileStorage`` reads it.
"""

from __future__ import annotations

import os
from dataclasses import dataclass
from pathlib import Path

import cv2
import numpy as np

from ..geometry.camera import check_intrinsics_for_size, validate_distortion, validate_intrinsics
from ..geometry.conventions import FloatArray
from .export import check_target, place_file

#: The suffixes :func:`save_calibration` writes (and :func:`load_calibration` reads).
CALIBRATION_SUFFIXES = (".yaml", ".yml", ".xml", ".json")

#: The largest image side a calibration file may give, in pixels (a sanity bound: the
#: largest camera sensors are about 20 000 pixels wide).
MAX_IMAGE_SIDE_PX = 100_000


@dataclass(frozen=True)
class CameraCalibration:
    """Intrinsics and distortion of a camera at a given image size, named as the file
    names them.

    ``K`` and ``dist`` are the same arrays under the names the rest of the library (and
    the book) gives them, ``SceneReconstruction3D(calib.K, calib.dist)``; they are aliases
    to stay, not deprecated: both pairs of names are in use, and neither is going away.

    Attributes
    ----------
    camera_matrix : (3, 3) float64
        The file's ``camera_matrix`` (OpenCV pixels).
    distortion_coefficients : (n,) float64
        The file's ``distortion_coefficients`` (OpenCV's order).
    image_size : tuple[int, int]
        (width, height) the calibration holds for (``image_width``, ``image_height``).
    """

    camera_matrix: FloatArray
    distortion_coefficients: FloatArray
    image_size: tuple[int, int]

    @property
    def K(self) -> FloatArray:
        """``camera_matrix`` ``(3, 3)``."""
        return self.camera_matrix

    @property
    def dist(self) -> FloatArray:
        """``distortion_coefficients`` ``(n,)``."""
        return self.distortion_coefficients


def _not_file_storage(path: Path) -> str:
    """What a file that OpenCV's FileStorage cannot read is: a bare 3x3 matrix (such as
    the Strecha scenes' K.txt) is told what the file must add."""
    try:
        bare = path.stat().st_size < 4096 and np.loadtxt(path, ndmin=2).shape == (3, 3)
    except (ValueError, OSError, UnicodeDecodeError):
        bare = False
    if bare:
        return ("it holds a bare 3x3 matrix, without the image size it is for: write it as "
                "OpenCV YAML with camera_matrix, distortion_coefficients, image_width and "
                "image_height (as calibrate.py does)")
    return "not OpenCV YAML/XML"


def load_calibration(path: str | os.PathLike) -> CameraCalibration:
    """Read a calibration file.

    Parameters
    ----------
    path : str or os.PathLike
        An OpenCV FileStorage file (``.yaml``, ``.yml``, ``.xml`` or ``.json``).

    Returns
    -------
    CameraCalibration
        ``camera_matrix`` ``(3, 3)`` (alias ``K``) and ``distortion_coefficients``
        (alias ``dist``) for images of its ``image_size`` ``(width, height)``.


    Raises
    ------
    FileNotFoundError
        If the file does not exist, or a folder stands there (saying which).
    ValueError
        If it is not FileStorage YAML/XML or lacks or garbles a required field.
    """
    path = Path(path)
    if not path.is_file():
        what = ("a folder, not a calibration file" if path.is_dir()
                else "calibration file not found")
        raise FileNotFoundError(f"{what}: '{path}'")
    try:
        fs = cv2.FileStorage(str(path), cv2.FILE_STORAGE_READ)
    except (cv2.error, SystemError) as exc:
        raise ValueError(f"cannot parse calibration file '{path}': "
                         f"{_not_file_storage(path)}") from exc
    try:
        if not fs.isOpened():
            raise ValueError(f"cannot open calibration file '{path}'")
        K = _matrix(fs, "camera_matrix")
        dist = _matrix(fs, "distortion_coefficients")
        size = tuple(_pixels(fs, key) for key in ("image_width", "image_height"))
    finally:
        fs.release()
    if K is None:
        raise ValueError(f"calibration file '{path}' has no 'camera_matrix' matrix")
    if None in size:
        raise ValueError(f"calibration file '{path}' needs 'image_width' and 'image_height' "
                         f"as whole numbers of pixels from 1 to {MAX_IMAGE_SIDE_PX}")
    try:
        K = validate_intrinsics(K)
        dist = validate_distortion(dist)
        check_intrinsics_for_size(K, size)
    except ValueError as exc:
        raise ValueError(f"calibration file '{path}': {exc}") from exc
    return CameraCalibration(K, dist, size)


def _matrix(fs: cv2.FileStorage, key: str) -> np.ndarray | None:
    """The matrix stored under ``key``, or None when there is none (or something else)."""
    node = fs.getNode(key)
    if not node.isMap():  # OpenCV stores a matrix as a map (rows, cols, dt, data)
        return None
    try:
        return node.mat()
    except cv2.error:
        return None


def _pixels(fs: cv2.FileStorage, key: str) -> int | None:
    """The whole number of pixels stored under ``key``, or None when it is not one."""
    node = fs.getNode(key)
    if not (node.isInt() or node.isReal()):
        return None
    value = node.real()
    if not (np.isfinite(value) and value == round(value) and 1 <= value <= MAX_IMAGE_SIDE_PX):
        return None
    return int(value)


def save_calibration(
    path: str | os.PathLike,
    camera: CameraCalibration,
    extras: dict | None = None,
    overwrite: bool = False,
) -> Path:
    """Write a calibration atomically; refuse to replace a file unless ``overwrite``.

    ``extras`` adds fields: numbers, strings, or arrays (written as matrices).

    Parameters
    ----------
    path : str or os.PathLike
        Target file, ending in .yaml, .yml, .xml or .json.
    camera : CameraCalibration
        The calibration to write.
    extras : dict or None, default None
        Further fields by name.
    overwrite : bool, default False
        Replace an existing file.

    Returns
    -------
    Path
        The file written.


    Raises
    ------
    FileExistsError
        If ``path`` exists and ``overwrite`` is False.
    ValueError
        If the suffix is not .yaml, .yml, .xml or .json.
    OSError
        If the file cannot be written (``IsADirectoryError``: a folder stands there).
    """
    path = Path(path)
    if path.suffix.lower() not in CALIBRATION_SUFFIXES:
        raise ValueError(f"calibration file must end in .yaml, .yml, .xml or .json, got '{path}'")
    if path.exists() and not overwrite:
        raise FileExistsError(f"'{path}' exists; pass overwrite=True to replace it")
    check_target(path)
    tmp = path.with_name(f".{path.stem}.tmp{path.suffix}")
    try:  # an unwritable folder fails here with its reason, not in OpenCV's log
        tmp.touch()
    except OSError as exc:
        raise OSError(exc.errno, exc.strerror, str(path)) from exc
    try:
        fs = cv2.FileStorage(str(tmp), cv2.FILE_STORAGE_WRITE)
        try:
            fs.write("image_width", int(camera.image_size[0]))
            fs.write("image_height", int(camera.image_size[1]))
            fs.write("camera_matrix", np.asarray(camera.camera_matrix, dtype=np.float64))
            fs.write("distortion_coefficients",
                     np.asarray(camera.distortion_coefficients, np.float64).reshape(1, -1))
            for key, value in (extras or {}).items():
                if isinstance(value, str):
                    fs.write(key, value)
                elif np.isscalar(value):
                    fs.write(key, float(value))
                else:
                    fs.write(key, np.asarray(value, dtype=np.float64))
        finally:
            fs.release()
    except cv2.error as exc:  # OpenCV says only "Emitter is not available" and the like
        tmp.unlink(missing_ok=True)
        raise OSError(f"cannot write the calibration file '{path}' (is its folder writable, "
                      "and is there space?)") from exc
    except BaseException:
        tmp.unlink(missing_ok=True)
        raise
    place_file(tmp, path)
    return path
