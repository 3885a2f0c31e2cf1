"""COLMAP binary models (``cameras.bin``, ``images.bin``, ``points3D.bin``) in and out.

The same :class:`~scene3D.io.colmap_model.ColmapModel` as the text files of
:mod:`scene3D.io.colmap`, in the same conventions (world-to-camera poses, OpenCV pixels:
COLMAP's half-pixel offset removed on the way in and put back on the way out). The
layout is COLMAP's (``src/colmap/scene/reconstruction_io.cc``), little-endian:

- ``cameras.bin``: ``uint64`` count; per camera ``uint32`` id, ``int32`` model id,
  ``uint64`` width and height, the model's parameters as ``float64``;
- ``images.bin``: ``uint64`` count; per image ``uint32`` id, ``qw qx qy qz tx ty tz``
  (``cam_from_world``) as ``float64``, ``uint32`` camera id, the name ending in a NUL
  byte, ``uint64`` count of 2D points, then per point ``x, y`` (``float64``) and its
  ``uint64`` 3D point id (``2**64 - 1``: none);
- ``points3D.bin``: ``uint64`` count; per point ``uint64`` id, ``x y z`` (``float64``),
  ``r g b`` (``uint8``), the error (``float64``), ``uint64`` track length, then per
  element ``uint32`` image id and ``uint32`` 2D point index.

Doubles are stored as they are: a model written here and read back has the same cameras,
translations and points to the last bit (the rotations to the rounding of the
quaternion), and is the same as the text model of :mod:`scene3D.io.colmap` read back.
The files COLMAP 3.12 adds beside the three (``rigs.bin``, ``frames.bin``) are not
read: each image is its own camera pose.
"""

from __future__ import annotations

import os
import struct
from collections.abc import Iterator
from pathlib import Path

import numpy as np

from ..geometry.conventions import quaternion_from_rotation
from .atomic import write_files
from .colmap_model import (
    CAMERA_MODELS,
    ColmapCamera,
    ColmapFormatError,
    ColmapModel,
    ImageRecord,
    PointRecord,
    model_from_records,
    point2d_indices,
)

#: The names of the three files of a binary model.
BINARY_FILES = ("cameras.bin", "images.bin", "points3D.bin")

#: COLMAP's ids of the camera models read and written (``CameraModelId``).
CAMERA_MODEL_IDS: dict[str, int] = {
    "SIMPLE_PINHOLE": 0, "PINHOLE": 1, "SIMPLE_RADIAL": 2, "RADIAL": 3, "OPENCV": 4,
    "FULL_OPENCV": 6,
}
#: COLMAP's names of the models it has and scene3D does not read, for messages.
OTHER_CAMERA_MODELS = {5: "OPENCV_FISHEYE", 7: "FOV", 8: "SIMPLE_RADIAL_FISHEYE",
                       9: "RADIAL_FISHEYE", 10: "THIN_PRISM_FISHEYE",
                       11: "RAD_TAN_THIN_PRISM_FISHEYE", 12: "SIMPLE_DIVISION",
                       13: "DIVISION", 14: "SIMPLE_FISHEYE", 15: "FISHEYE"}
#: The 3D point id of a 2D point that belongs to none.
NO_POINT = 2**64 - 1

_CAMERA = struct.Struct("<IiQQ")
_IMAGE = struct.Struct("<I7dI")
_POINT = struct.Struct("<Q3d3BdQ")
_COUNT = struct.Struct("<Q")
_POINT2D = np.dtype([("xy", "<f8", 2), ("id", "<u8")])
_TRACK = np.dtype("<u4")


class _Reader:
    """Reads little-endian records from the bytes of one file, naming it when short."""

    def __init__(self, path: Path) -> None:
        try:
            self.data = path.read_bytes()
        except FileNotFoundError:
            raise FileNotFoundError(2, "COLMAP model file not found", str(path)) from None
        self.path = path
        self.offset = 0

    def take(self, size: int, what: str) -> int:
        """The offset of the next ``size`` bytes, which are then passed."""
        start = self.offset
        if start + size > len(self.data):
            raise ColmapFormatError(f"'{self.path}': the file ends inside {what} (at byte "
                                    f"{len(self.data)}, {start + size} needed)")
        self.offset += size
        return start

    def unpack(self, layout: struct.Struct, what: str) -> tuple:
        return layout.unpack_from(self.data, self.take(layout.size, what))

    def array(self, dtype: np.dtype, count: int, what: str) -> np.ndarray:
        start = self.take(dtype.itemsize * count, what)
        return np.frombuffer(self.data, dtype, count, start)

    def name(self, what: str) -> str:
        end = self.data.find(b"\0", self.offset)
        if end < 0:
            raise ColmapFormatError(f"'{self.path}': {what} has no end (NUL byte)")
        start = self.take(end + 1 - self.offset, what)
        return self.data[start:end].decode("utf-8", errors="replace")

    def finish(self) -> None:
        if self.offset != len(self.data):
            raise ColmapFormatError(f"'{self.path}': {len(self.data) - self.offset} bytes "
                                    "after the last record")


def read_cameras_binary(path: str | os.PathLike) -> dict[int, ColmapCamera]:
    """The cameras of a ``cameras.bin``, by id.

    Parameters
    ----------
    path : str or os.PathLike
        A COLMAP ``cameras.bin``.

    Returns
    -------
    dict[int, ColmapCamera]


    Raises
    ------
    FileNotFoundError
        The file is missing.
    ColmapFormatError
        A camera model other than :data:`~scene3D.io.colmap_model.CAMERA_MODELS` (the
        message names it and the file), or a file cut short.
    """
    reader = _Reader(Path(path))
    names = {i: name for name, i in CAMERA_MODEL_IDS.items()}
    cameras = {}
    for k in range(reader.unpack(_COUNT, "the camera count")[0]):
        cam_id, model_id, width, height = reader.unpack(_CAMERA, f"camera {k + 1}")
        model = names.get(model_id)
        if model is None:
            other = OTHER_CAMERA_MODELS.get(model_id, f"number {model_id}")
            raise ColmapFormatError(f"'{reader.path}': camera {cam_id} has the camera model "
                                    f"{other}, which is not supported (supported: "
                                    f"{', '.join(CAMERA_MODELS)})")
        params = reader.array(np.dtype("<f8"), len(CAMERA_MODELS[model]),
                              f"camera {cam_id}'s parameters")
        cameras[cam_id] = ColmapCamera(model, width, height, tuple(params.tolist()))
    reader.finish()
    return cameras


def _read_images(path: Path) -> list[ImageRecord]:
    reader = _Reader(path)
    images = []
    for k in range(reader.unpack(_COUNT, "the image count")[0]):
        image_id, *pose, cam_id = reader.unpack(_IMAGE, f"image {k + 1}")
        name = reader.name(f"image {image_id}'s name")
        count = reader.unpack(_COUNT, f"image {image_id}'s 2D point count")[0]
        points2d = reader.array(_POINT2D, count, f"image {image_id}'s 2D points")
        images.append((image_id, tuple(pose), cam_id, name, points2d["xy"].copy()))
    reader.finish()
    return images


def _read_points(path: Path) -> Iterator[PointRecord]:
    reader = _Reader(path)
    for k in range(reader.unpack(_COUNT, "the point count")[0]):
        point_id, x, y, z, r, g, b, error, length = reader.unpack(_POINT, f"point {k + 1}")
        track = reader.array(_TRACK, 2 * length, f"point {point_id}'s track")
        yield (f"'{path}' point {point_id}", point_id, (x, y, z), (r, g, b), error,
               track.astype(np.int64).reshape(-1, 2))
    reader.finish()


def read_colmap_binary(folder: str | os.PathLike) -> ColmapModel:
    """Read a COLMAP binary model from ``folder`` (its ``cameras.bin``, ``images.bin`` and
    ``points3D.bin``) in scene3D's conventions, as
    :func:`scene3D.io.colmap.read_colmap_text` reads the text form.

    Parameters
    ----------
    folder : str or os.PathLike
        Folder holding the three files.

    Returns
    -------
    ColmapModel
        World-to-camera poses (``x_cam = R X + t``) and OpenCV pixels.


    Raises
    ------
    FileNotFoundError
        ``folder`` or one of the three files is missing (the error names the file).
    ColmapFormatError
        An unsupported camera model (named, with the file), a file cut short or with
        bytes after its last record, an image of an unknown camera, a track naming an
        unknown image or 2D point.
    """
    folder = Path(folder)
    if not folder.is_dir():
        raise FileNotFoundError(2, "COLMAP model folder not found", str(folder))
    cameras = read_cameras_binary(folder / "cameras.bin")
    images = _read_images(folder / "images.bin")
    points = list(_read_points(folder / "points3D.bin"))
    return model_from_records(cameras, images, points, str(folder / "images.bin"))


def colmap_binary(model: ColmapModel) -> dict[str, bytes]:
    """``model`` as the three files of a COLMAP binary model (name -> bytes).

    Parameters
    ----------
    model : ColmapModel
        The model to write.

    Returns
    -------
    dict[str, bytes]
        ``cameras.bin``, ``images.bin`` and ``points3D.bin`` by name.
    """
    cameras = [_COUNT.pack(len(model.cameras))]
    for cam_id in sorted(model.cameras):
        c = model.cameras[cam_id]
        cameras += [_CAMERA.pack(cam_id, CAMERA_MODEL_IDS[c.model], c.width, c.height),
                    np.asarray(c.params, "<f8").tobytes()]
    index = point2d_indices(model)
    images = [_COUNT.pack(len(model.names))]
    for v, name in enumerate(model.names):
        mine = np.nonzero(model.obs_view == v)[0]
        points2d = np.empty(len(mine), _POINT2D)
        points2d["xy"] = model.obs_xy[mine] + 0.5
        points2d["id"] = model.point_ids[model.obs_point[mine]]
        images += [_IMAGE.pack(int(model.image_ids[v]), *quaternion_from_rotation(model.R[v]),
                               *model.t[v], int(model.camera_ids[v])),
                   name.encode("utf-8") + b"\0", _COUNT.pack(len(mine)), points2d.tobytes()]
    points = [_COUNT.pack(len(model.points3d))]
    order = np.argsort(model.obs_point, kind="stable")
    starts = np.searchsorted(model.obs_point[order], np.arange(len(model.points3d) + 1))
    for p in range(len(model.points3d)):
        ks = order[starts[p]:starts[p + 1]]
        track = np.column_stack([model.image_ids[model.obs_view[ks]], index[ks]])
        points += [_POINT.pack(int(model.point_ids[p]), *model.points3d[p],
                               *(int(c) for c in model.colors[p]),
                               float(model.errors_px[p]), len(ks)),
                   track.astype(_TRACK).tobytes()]
    return {"cameras.bin": b"".join(cameras), "images.bin": b"".join(images),
            "points3D.bin": b"".join(points)}


def write_colmap_binary(folder: str | os.PathLike, model: ColmapModel) -> list[Path]:
    """Write ``model`` as a COLMAP binary model into ``folder`` (created if needed), each
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
    return write_files(folder, colmap_binary(model))
