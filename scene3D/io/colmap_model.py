"""The data of a COLMAP model in scene3D's conventions: cameras, images, points.

:class:`ColmapModel` and :class:`ColmapCamera` as :mod:`scene3D.io.colmap` (text) and
:mod:`scene3D.io.colmap_binary` read and write them (world-to-camera poses
``x_cam = R @ X + t``, pixels in the OpenCV convention, OpenCV ``K`` and distortion), the
model assembled from a file's records (:func:`model_from_records`, shared by both
readers), and the projection through a camera.
"""

from __future__ import annotations

from collections.abc import Iterable
from dataclasses import dataclass
from pathlib import Path

import cv2
import numpy as np
from numpy.typing import ArrayLike

from ..geometry.camera import validate_distortion
from ..geometry.conventions import (
    FloatArray,
    camera_centers,
    rotation_from_quaternion,
)

#: The COLMAP camera models read and written, with their parameters in file order.
CAMERA_MODELS: dict[str, tuple[str, ...]] = {
    "SIMPLE_PINHOLE": ("f", "cx", "cy"),
    "PINHOLE": ("fx", "fy", "cx", "cy"),
    "SIMPLE_RADIAL": ("f", "cx", "cy", "k"),
    "RADIAL": ("f", "cx", "cy", "k1", "k2"),
    "OPENCV": ("fx", "fy", "cx", "cy", "k1", "k2", "p1", "p2"),
    "FULL_OPENCV": ("fx", "fy", "cx", "cy", "k1", "k2", "p1", "p2", "k3", "k4", "k5", "k6"),
}

#: The names of the three files of a text model.
MODEL_FILES = ("cameras.txt", "images.txt", "points3D.txt")


class ColmapFormatError(ValueError):
    """A COLMAP file that cannot be read: the message names the file, and the line (text)
    or the record (binary)."""


@dataclass(frozen=True)
class ColmapCamera:
    """One camera of a COLMAP model.

    Attributes
    ----------
    model : str
        COLMAP's model name, one of :data:`CAMERA_MODELS`.
    width, height : int
        Size of the images in pixels.
    params : tuple[float, ...]
        The parameters as COLMAP stores them (principal point with pixel centres at
        +0.5), in the order of ``CAMERA_MODELS[model]``.
    """

    model: str
    width: int
    height: int
    params: tuple[float, ...]

    def __post_init__(self) -> None:
        if self.model not in CAMERA_MODELS:
            raise ValueError(f"camera model '{self.model}' is not supported (supported: "
                             f"{', '.join(CAMERA_MODELS)})")
        if len(self.params) != len(CAMERA_MODELS[self.model]):
            raise ValueError(f"camera model {self.model} has {len(CAMERA_MODELS[self.model])} "
                             f"parameters, got {len(self.params)}")

    @property
    def image_size(self) -> tuple[int, int]:
        """(width, height) in pixels."""
        return (self.width, self.height)

    @property
    def _named(self) -> dict[str, float]:
        return dict(zip(CAMERA_MODELS[self.model], self.params))

    @property
    def K(self) -> FloatArray:
        """Intrinsics ``(3, 3)`` in the OpenCV pixel convention."""
        p = self._named
        fx, fy = p.get("fx", p.get("f")), p.get("fy", p.get("f"))
        return np.array([[fx, 0.0, p["cx"] - 0.5], [0.0, fy, p["cy"] - 0.5], [0.0, 0.0, 1.0]])

    @property
    def dist(self) -> FloatArray:
        """OpenCV distortion coefficients: ``(0,)`` for the pinhole models, else
        ``(k1, k2, p1, p2)`` or, for FULL_OPENCV, ``(k1, k2, p1, p2, k3, k4, k5, k6)``."""
        p = self._named
        if self.model in ("SIMPLE_PINHOLE", "PINHOLE"):
            return np.zeros(0)
        if self.model == "SIMPLE_RADIAL":
            return np.array([p["k"], 0.0, 0.0, 0.0])
        if self.model == "RADIAL":
            return np.array([p["k1"], p["k2"], 0.0, 0.0])
        return np.array([p[name] for name in CAMERA_MODELS[self.model][4:]])

    @classmethod
    def from_opencv(cls, K: ArrayLike, dist: ArrayLike | None,
                    image_size: tuple[int, int]) -> ColmapCamera:
        """The camera of OpenCV's ``K`` ``(3, 3)`` and ``dist`` for images of
        ``image_size`` (width, height): PINHOLE without distortion, SIMPLE_RADIAL or
        RADIAL with ``k1[, k2]`` only and square pixels, OPENCV with ``k1, k2, p1, p2``,
        FULL_OPENCV with ``k3``..``k6``.

        Parameters
        ----------
        K : (3, 3) array_like
            Intrinsics (OpenCV pixels, no skew).
        dist : array_like or None
            OpenCV distortion coefficients; None for none.
        image_size : (int, int)
            ``(width, height)`` in px.

        Returns
        -------
        ColmapCamera


        Raises
        ------
        ValueError
            ``K`` has a skew, or ``dist`` has thin-prism or tilt terms (COLMAP's
            perspective models have neither).
        """
        K = np.asarray(K, dtype=np.float64)
        if K.shape != (3, 3):
            raise ValueError(f"`K` must have shape (3, 3), got {K.shape}")
        if K[0, 1] != 0:
            raise ValueError(f"`K` has a skew ({K[0, 1]:g}), which COLMAP's models cannot hold")
        d = np.zeros(14)
        given = validate_distortion(dist)
        d[:given.size] = given
        if np.any(d[8:] != 0):
            raise ValueError("`dist` has thin-prism or tilt coefficients, which COLMAP's "
                             "perspective models cannot hold")
        base = (K[0, 0], K[1, 1], K[0, 2] + 0.5, K[1, 2] + 0.5)
        width, height = (int(v) for v in image_size)
        if np.any(d[4:8] != 0):
            return cls("FULL_OPENCV", width, height, tuple(float(v) for v in (*base, *d[:8])))
        if np.any(d[:4] != 0):
            if K[0, 0] == K[1, 1] and not np.any(d[2:4]):  # radial only, square pixels
                simple = (K[0, 0], *base[2:], d[0]) + ((d[1],) if d[1] else ())
                return cls("RADIAL" if d[1] else "SIMPLE_RADIAL", width, height,
                           tuple(float(v) for v in simple))
            return cls("OPENCV", width, height, tuple(float(v) for v in (*base, *d[:4])))
        return cls("PINHOLE", width, height, tuple(float(v) for v in base))


@dataclass(frozen=True)
class ColmapModel:
    """Cameras, image poses and points of a COLMAP model, in scene3D's conventions.

    ``V`` images (in the order of their ids), ``P`` points, ``O`` observations.

    Attributes
    ----------
    cameras : dict[int, ColmapCamera]
        By camera id.
    image_ids : (V,) int
    names : tuple[str, ...]
        The image names (paths relative to the image folder).
    camera_ids : (V,) int
        The camera of each image.
    R : (V, 3, 3) float64
        World-to-camera rotations, ``x_cam = R @ X + t``.
    t : (V, 3) float64
        World-to-camera translations.
    point_ids : (P,) int
    points3d : (P, 3) float64
        Points in the world frame.
    colors : (P, 3) uint8
        RGB colour of each point.
    errors_px : (P,) float64
        The mean reprojection error of each point, as the file says.
    obs_view : (O,) int
        Index (into ``names``) of the image of each observation.
    obs_point : (O,) int
        Index (into ``points3d``) of its point.
    obs_xy : (O, 2) float64
        Its pixel, OpenCV convention.
    """

    cameras: dict[int, ColmapCamera]
    image_ids: np.ndarray
    names: tuple[str, ...]
    camera_ids: np.ndarray
    R: FloatArray
    t: FloatArray
    point_ids: np.ndarray
    points3d: FloatArray
    colors: np.ndarray
    errors_px: FloatArray
    obs_view: np.ndarray
    obs_point: np.ndarray
    obs_xy: FloatArray

    @property
    def centers(self) -> FloatArray:
        """Camera centres ``C = -R^T t`` ``(V, 3)`` in the world frame."""
        return camera_centers(self.R, self.t)

    def camera(self, view: int) -> ColmapCamera:
        """The camera of image ``view`` (an index into ``names``).

        Parameters
        ----------
        view : int
            Index into ``names``.

        Returns
        -------
        ColmapCamera
        """
        return self.cameras[int(self.camera_ids[view])]

    def reprojection_errors_px(self) -> FloatArray:
        """The distance in pixels between each observation and its point projected with
        its image's camera (distortion included) ``(O,)``."""
        errors = np.empty(len(self.obs_view))
        for v in range(len(self.names)):
            mine = np.nonzero(self.obs_view == v)[0]
            if mine.size == 0:
                continue
            camera = self.camera(v)
            projected = project_points(self.points3d[self.obs_point[mine]], camera.K,
                                       camera.dist, self.R[v], self.t[v])
            errors[mine] = np.linalg.norm(projected - self.obs_xy[mine], axis=1)
        return errors

    def point_errors_px(self) -> FloatArray:
        """The mean of :meth:`reprojection_errors_px` over each point's observations
        ``(P,)`` (0 for a point without any)."""
        sums = np.bincount(self.obs_point, self.reprojection_errors_px(),
                           minlength=len(self.points3d))
        counts = np.bincount(self.obs_point, minlength=len(self.points3d))
        return sums / np.maximum(counts, 1)


def project_points(points3d: FloatArray, K: FloatArray, dist: FloatArray, R: FloatArray,
                   t: FloatArray) -> FloatArray:
    """Pixels ``(N, 2)`` of world points ``(N, 3)`` in a camera ``x_cam = R X + t`` with
    intrinsics ``K`` and OpenCV distortion ``dist`` (OpenCV pixel convention).

    Parameters
    ----------
    points3d : (N, 3) array_like
        World points.
    K : (3, 3) array_like
        Intrinsics (OpenCV pixels).
    dist : (n,) array_like
        OpenCV distortion coefficients (empty for none).
    R, t : (3, 3), (3,) array_like
        World-to-camera pose.

    Returns
    -------
    (N, 2) float64 ndarray
    """
    if len(points3d) == 0:
        return np.zeros((0, 2))
    cam = np.asarray(points3d, np.float64) @ np.asarray(R).T + np.asarray(t)
    return distorted_pixels(cam[:, :2] / cam[:, 2:], K, dist)


def distorted_pixels(normalized: FloatArray, K: FloatArray, dist: FloatArray) -> FloatArray:
    """Pixels of normalized image coordinates through ``dist`` and ``K``.

    Parameters
    ----------
    normalized : (N, 2) float64
        ``(X / Z, Y / Z)`` of camera-frame points.
    K : (3, 3) float64
    dist : (k,) float64
        OpenCV distortion coefficients (empty or zero: none).

    Returns
    -------
    (N, 2) float64
        Pixels, OpenCV convention.
    """
    if dist.size == 0 or not np.any(dist):
        return normalized @ K[:2, :2].T + K[:2, 2]
    rays = np.column_stack([normalized, np.ones(len(normalized))])
    pixels, _ = cv2.projectPoints(rays.reshape(-1, 1, 3), np.zeros(3), np.zeros(3), K, dist)
    return pixels.reshape(-1, 2).astype(np.float64)


#: One image as a model file stores it: image id, ``(qw, qx, qy, qz, tx, ty, tz)``
#: (``cam_from_world``), camera id, name, and its 2D points ``(n, 2)`` in COLMAP pixels.
ImageRecord = tuple[int, tuple[float, ...], int, str, FloatArray]

#: One point as a model file stores it: where it is (``"'points3D.txt' line 7"``, for
#: messages), point id, ``(x, y, z)``, ``(r, g, b)``, error, and its track ``(k, 2)`` of
#: (image id, 2D point index).
PointRecord = tuple[str, int, tuple[float, ...], tuple[float, ...], float, np.ndarray]


def model_from_records(cameras: dict[int, ColmapCamera], images: list[ImageRecord],
                       points: Iterable[PointRecord], images_file: str) -> ColmapModel:
    """The model of a file's records, in scene3D's conventions, checked.

    Images are put in the order of their ids; observations come from the points'
    tracks, image by image in the order of their 2D points (2D points of no 3D point are
    not kept), with COLMAP's half-pixel offset removed.

    Parameters
    ----------
    cameras : dict[int, ColmapCamera]
        By camera id.
    images : list of ImageRecord
        Each image's id, pose, camera id, name and 2D points (:data:`ImageRecord`).
    points : iterable of PointRecord
        Each point with its track (:data:`PointRecord`).
    images_file : str
        The images' file, for messages.

    Returns
    -------
    ColmapModel


    Raises
    ------
    ColmapFormatError
        An image of an unknown camera, an image id given twice, a track naming an
        unknown image or 2D point.
    """
    images = sorted(images, key=lambda image: image[0])
    images_name = Path(images_file).name
    cameras_name = "cameras" + Path(images_file).suffix
    view_of = {}
    for v, (image_id, _, cam_id, name, _) in enumerate(images):
        if cam_id not in cameras:
            raise ColmapFormatError(f"'{images_file}': image {image_id} ('{name}') has "
                                    f"camera {cam_id}, which {cameras_name} does not list")
        if image_id in view_of:
            raise ColmapFormatError(f"'{images_file}': image id {image_id} comes twice")
        view_of[image_id] = v
    R = np.array([rotation_from_quaternion(im[1][:4]) for im in images]).reshape(-1, 3, 3)
    t = np.array([im[1][4:] for im in images], dtype=np.float64).reshape(-1, 3)
    ids, xyz, rgb, errors = [], [], [], []
    obs_view, obs_point, obs_index, obs_xy = [], [], [], []
    for where, point_id, X, color, error, track in points:
        p = len(ids)
        ids.append(point_id)
        xyz.append(X)
        rgb.append(color)
        errors.append(error)
        for image_id, index in track.tolist():
            v = view_of.get(image_id)
            if v is None:
                raise ColmapFormatError(f"{where}: point {point_id} is seen in image "
                                        f"{image_id}, which {images_name} does not list")
            points2d = images[v][4]
            if not 0 <= index < len(points2d):
                raise ColmapFormatError(f"{where}: point {point_id} is 2D point {index} of "
                                        f"image {image_id}, which has {len(points2d)}")
            obs_view.append(v)
            obs_point.append(p)
            obs_index.append(index)
            obs_xy.append(points2d[index] - 0.5)
    order = np.lexsort((obs_index, obs_view))  # image by image, as their 2D points
    return ColmapModel(
        cameras=cameras, image_ids=np.array([im[0] for im in images], dtype=np.int64),
        names=tuple(im[3] for im in images),
        camera_ids=np.array([im[2] for im in images], dtype=np.int64), R=R, t=t,
        point_ids=np.array(ids, dtype=np.int64),
        points3d=np.array(xyz, dtype=np.float64).reshape(-1, 3),
        colors=np.array(rgb, dtype=np.float64).reshape(-1, 3).clip(0, 255).astype(np.uint8),
        errors_px=np.array(errors, dtype=np.float64),
        obs_view=np.array(obs_view, dtype=np.int64)[order],
        obs_point=np.array(obs_point, dtype=np.int64)[order],
        obs_xy=np.array(obs_xy, dtype=np.float64).reshape(-1, 2)[order])


def point2d_indices(model: ColmapModel) -> np.ndarray:
    """The index of each observation ``(O,)`` among its image's 2D points, as the writers
    number them: image by image, in the order of ``obs_view``.

    Parameters
    ----------
    model : ColmapModel

    Returns
    -------
    (O,) int64 ndarray
    """
    index = np.zeros(len(model.obs_view), dtype=np.int64)
    for v in range(len(model.names)):
        mine = np.nonzero(model.obs_view == v)[0]
        index[mine] = np.arange(len(mine))
    return index
