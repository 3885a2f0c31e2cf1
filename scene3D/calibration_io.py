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

from .camera import validate_distortion, validate_intrinsics
from .geometry import FloatArray

_SUFFIXES = (".yaml", ".yml", ".xml", ".json")


@dataclass(frozen=True)
class CameraCalibration:
    """Intrinsics and distortion of a camera at a given image size.

    Attributes
    ----------
    K : (3, 3) float64
    dist : (n,) float64
        OpenCV distortion coefficients.
    image_size : tuple[int, int]
        (width, height) the calibration holds for.
    """

    K: FloatArray
    dist: FloatArray
    image_size: tuple[int, int]


def load_calibration(path: str | os.PathLike) -> CameraCalibration:
    """Read a calibration file.

    Raises
    ------
    FileNotFoundError
        If the file does not exist.
    ValueError
        If it is not FileStorage YAML/XML or lacks or garbles a required field.
    """
    path = Path(path)
    if not path.is_file():
        raise FileNotFoundError(f"calibration file not found: '{path}'")
    try:
        fs = cv2.FileStorage(str(path), cv2.FILE_STORAGE_READ)
    except (cv2.error, SystemError) as exc:
        raise ValueError(f"cannot parse calibration file '{path}': not OpenCV YAML/XML") from exc
    try:
        if not fs.isOpened():
            raise ValueError(f"cannot open calibration file '{path}'")
        K = fs.getNode("camera_matrix").mat()
        dist = fs.getNode("distortion_coefficients").mat()
        width = fs.getNode("image_width").real()
        height = fs.getNode("image_height").real()
    finally:
        fs.release()
    if K is None:
        raise ValueError(f"calibration file '{path}' has no 'camera_matrix' matrix")
    if width <= 0 or height <= 0:
        raise ValueError(
            f"calibration file '{path}' needs positive 'image_width' and 'image_height'"
        )
    try:
        K = validate_intrinsics(K)
        dist = validate_distortion(dist)
    except ValueError as exc:
        raise ValueError(f"calibration file '{path}': {exc}") from exc
    return CameraCalibration(K, dist, (int(width), int(height)))


def save_calibration(
    path: str | os.PathLike,
    camera: CameraCalibration,
    extras: dict | None = None,
    overwrite: bool = False,
) -> Path:
    """Write a calibration atomically; refuse to replace a file unless ``overwrite``.

    ``extras`` adds fields: numbers, strings, or arrays (written as matrices).

    Raises
    ------
    FileExistsError
        If ``path`` exists and ``overwrite`` is False.
    ValueError
        If the suffix is not .yaml, .yml, .xml or .json.
    """
    path = Path(path)
    if path.suffix.lower() not in _SUFFIXES:
        raise ValueError(f"calibration file must end in .yaml, .yml, .xml or .json, got '{path}'")
    if path.exists() and not overwrite:
        raise FileExistsError(f"'{path}' exists; use --force to overwrite it")
    tmp = path.with_name(f".{path.stem}.tmp{path.suffix}")
    fs = cv2.FileStorage(str(tmp), cv2.FILE_STORAGE_WRITE)
    try:
        fs.write("image_width", int(camera.image_size[0]))
        fs.write("image_height", int(camera.image_size[1]))
        fs.write("camera_matrix", np.asarray(camera.K, dtype=np.float64))
        fs.write("distortion_coefficients", np.asarray(camera.dist, np.float64).reshape(1, -1))
        for key, value in (extras or {}).items():
            if isinstance(value, str):
                fs.write(key, value)
            elif np.isscalar(value):
                fs.write(key, float(value))
            else:
                fs.write(key, np.asarray(value, dtype=np.float64))
    finally:
        fs.release()
    try:
        os.replace(tmp, path)
    finally:
        tmp.unlink(missing_ok=True)
    return path
