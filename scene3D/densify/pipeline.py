"""From a sparse model and its photos to a fused dense cloud: the chain the command runs.

:func:`densify` reads nothing but images: it takes a sparse model
(:class:`~scene3D.io.colmap_model.ColmapModel`, from :func:`load_sparse_model` or a
reconstruction in memory), chooses each view's neighbours and depth range
(:mod:`scene3D.densify.views`), computes the depth maps as independent tasks on an engine
(:func:`view_depth`, one a view, :mod:`scene3D.engines`) and fuses them
(:mod:`scene3D.densify.fusion`).
"""

from __future__ import annotations

import logging
import os
import time
from dataclasses import dataclass, field
from pathlib import Path

import cv2
import numpy as np

from ..engines import Engine, LocalEngine
from ..errors import ReconstructionError
from ..geometry.camera import scale_intrinsics_halved
from ..geometry.conventions import FloatArray
from ..io.colmap import find_model_folder, read_colmap_model
from ..io.colmap_binary import BINARY_FILES
from ..io.colmap_model import MODEL_FILES as TEXT_FILES
from ..io.colmap_model import ColmapModel
from ..io.images import load_working_image
from .fusion import DenseCloud, ViewDepth, depth_normals, footprint, fuse_depth_maps
from .preview import DepthPreview, depth_preview
from .sgbm import sgbm_depth
from .sweep import SweepSettings, plane_sweep_depth
from .views import choose_neighbours, depth_range, neighbour_scores

logger = logging.getLogger(__name__)

#: How a depth map is made (:class:`DenseSettings`).
DEPTH_METHODS = ("sweep", "sgbm")


class DenseInputError(ValueError):
    """A model or image folder that cannot be densified: the message says why.

    Attributes
    ----------
    reason : str
        ``"no_model"``, ``"one_view"`` or ``"missing_images"``.
    """

    def __init__(self, reason: str, message: str) -> None:
        super().__init__(message)
        self.reason = reason


@dataclass(frozen=True)
class DenseSettings:
    """How :func:`densify` works.

    Attributes
    ----------
    max_width : int or None
        The photos are halved while wider than this (None: full size).
    neighbours : int
        Neighbours a depth map is matched against.
    fusion_views : int
        Views a depth is checked against in fusion (the best by neighbour score).
    depth_tol : float
        Fusion's largest depth difference, as a share of the depth.
    reprojection_tol_px : float
        Fusion's largest reprojection distance (px).
    min_agree : int
        Least number of other views that must agree with a depth.
    voxel_px : float
        The thinning voxel's side in pixel footprints (:func:`~scene3D.densify.fusion.footprint`).
    sweep : SweepSettings
        The plane sweep's matching.
    method : str
        ``"sweep"`` (:mod:`scene3D.densify.sweep`) or ``"sgbm"``, rectified semi-global
        matching against each neighbour (:mod:`scene3D.densify.sgbm`; views of one camera
        matrix only): docs/dense.md compares the two.
    """

    max_width: int | None = 1536
    neighbours: int = 4
    fusion_views: int = 8
    depth_tol: float = 0.01
    reprojection_tol_px: float = 1.0
    min_agree: int = 2
    voxel_px: float = 1.0
    sweep: SweepSettings = field(default_factory=SweepSettings)
    method: str = "sweep"

    def __post_init__(self) -> None:
        if self.method not in DEPTH_METHODS:
            raise ValueError(f"`method` must be one of {', '.join(DEPTH_METHODS)}, got "
                             f"{self.method!r}")


@dataclass(frozen=True)
class DenseResult:
    """What :func:`densify` made.

    Attributes
    ----------
    cloud : DenseCloud
        The fused cloud (world frame of the model).
    previews : list of DepthPreview or None
        A small copy of each view's depth map (:mod:`scene3D.densify.preview`), in the
        order of the model's images (None for a view that shares no sparse point with
        another); the full maps are let go after fusion.
    neighbours : list of list of int
        Each view's neighbours (indices into the model's images).
    depth_ranges : list of (float, float) or None
        Each view's searched ``(near, far)`` (None for a view that sees too few sparse
        points to bound its depths: it gets no depth map, a warning says so).
    voxel_size : float
        The thinning voxel's side (the model's units).
    timings_s : dict[str, float]
        ``"depth_maps"``, ``"fusion"``.
    """

    cloud: DenseCloud
    previews: list[DepthPreview | None]
    neighbours: list[list[int]]
    depth_ranges: list[tuple[float, float] | None]
    voxel_size: float
    timings_s: dict[str, float]


def load_sparse_model(path: str | os.PathLike) -> ColmapModel:
    """The sparse model in ``path``: a ``reconstruct-views`` output folder (its
    ``colmap/`` model) or a folder holding a COLMAP model, binary or text
    (:func:`scene3D.io.colmap.read_colmap_model`: the binary files when all three are
    there, as COLMAP reads them).

    Parameters
    ----------
    path : str or os.PathLike
        The folder.

    Returns
    -------
    ColmapModel

    Raises
    ------
    DenseInputError
        No model there (``"no_model"``), a model with fewer than two images
        (``"one_view"``).
    ColmapFormatError
        A malformed model.
    """
    path = Path(path)
    if not path.is_dir():
        raise DenseInputError("no_model", f"model folder not found: '{path}'")
    folder = find_model_folder(path)
    if folder is None:
        raise DenseInputError("no_model", f"'{path}' holds no COLMAP model "
                              f"({', '.join(TEXT_FILES)}, or {', '.join(BINARY_FILES)}), "
                              "nor a colmap/ folder with one")
    model = read_colmap_model(folder)
    if len(model.names) < 2:
        raise DenseInputError("one_view", f"the model in '{path}' has "
                              f"{len(model.names)} image(s): dense matching needs at least "
                              "two views of the scene")
    return model


def image_paths(model: ColmapModel, images: str | os.PathLike) -> list[Path]:
    """The photo of each image of ``model`` in the folder ``images``.

    Parameters
    ----------
    model : ColmapModel
    images : str or os.PathLike
        The folder its image names are relative to.

    Returns
    -------
    list of Path

    Raises
    ------
    DenseInputError
        ``"missing_images"``: the folder or some of the photos are missing.
    """
    folder = Path(images)
    if not folder.is_dir():
        raise DenseInputError("missing_images", f"image folder not found: '{folder}'")
    paths = [folder / name for name in model.names]
    missing = [p for p in paths if not p.is_file()]
    if missing:
        more = f" and {len(missing) - 1} more" if len(missing) > 1 else ""
        raise DenseInputError("missing_images", f"{len(missing)} of the model's "
                              f"{len(paths)} images are not in '{folder}': "
                              f"'{missing[0].name}'{more}")
    return paths


def working_view(path: Path, K: FloatArray, dist: FloatArray,
                 max_width: int | None) -> tuple[np.ndarray, FloatArray]:
    """The undistorted working image ``(h, w, 3)`` BGR of a photo and its intrinsics
    ``(3, 3)`` (:func:`scene3D.io.images.load_working_image`).

    Parameters
    ----------
    path : Path
        The photo.
    K : (3, 3) ndarray
        Its intrinsics at its own size.
    dist : (n,) ndarray
        Its OpenCV distortion coefficients.
    max_width : int or None
        Halved while wider than this.

    Returns
    -------
    image : (h, w, 3) uint8 ndarray
    K : (3, 3) float64 ndarray
    """
    img, _, levels = load_working_image(path, K, dist, max_width, name=path.name)
    return img, scale_intrinsics_halved(K, levels)


def view_depth(reference: tuple, neighbours: list[tuple], depth_range: tuple[float, float],
               max_width: int | None, settings: SweepSettings,
               method: str = "sweep") -> ViewDepth:
    """One view's depth map, normals and colours: a task for an engine.

    Parameters
    ----------
    reference : (Path, K, dist, R, t)
        The reference photo, its intrinsics ``(3, 3)`` and distortion at its own size,
        and its world-to-camera pose.
    neighbours : list of (Path, K, dist, R, t)
        The same for each neighbour.
    depth_range : (float, float)
        ``(near, far)`` searched.
    max_width : int or None
        The working width.
    settings : SweepSettings
        The plane sweep's matching.
    method : str, default "sweep"
        ``"sweep"`` or ``"sgbm"`` (:class:`DenseSettings`).

    Returns
    -------
    ViewDepth

    Raises
    ------
    ValueError
        ``"sgbm"`` for views of different camera matrices.
    """
    path, K, dist, R, t = reference
    img, K_ref = working_view(path, K, dist, max_width)
    grey = cv2.cvtColor(img, cv2.COLOR_BGR2GRAY)
    matched = []
    for nb_path, nb_K, nb_dist, nb_R, nb_t in neighbours:
        nb_img, K_nb = working_view(nb_path, nb_K, nb_dist, max_width)
        R_rel = nb_R @ R.T
        matched.append((nb_img, K_nb, R_rel, nb_t - R_rel @ t))
    if method == "sgbm":
        if any(not np.allclose(K_nb, K_ref) for _, K_nb, _, _ in matched):
            raise ValueError("SGBM depth maps need views of one camera matrix")
        depth = sgbm_depth(img, K_ref, [(im, R_, t_) for im, _, R_, t_ in matched],
                           depth_range)
    else:
        depth, _ = plane_sweep_depth(grey, K_ref, [
            (cv2.cvtColor(im, cv2.COLOR_BGR2GRAY), K_, R_, t_) for im, K_, R_, t_ in matched],
            depth_range, settings)
    return ViewDepth(depth, depth_normals(depth, K_ref), img[:, :, ::-1].copy(), K_ref,
                     np.asarray(R, np.float64), np.asarray(t, np.float64))


def densify(model: ColmapModel, paths: list[Path], settings: DenseSettings | None = None,
            engine: Engine | None = None) -> DenseResult:
    """Depth maps of every view of ``model`` from its photos ``paths``, fused into one
    cloud (module docstring).

    Parameters
    ----------
    model : ColmapModel
        The sparse model (world-to-camera poses, points, observations).
    paths : list of Path
        The photo of each of its images (:func:`image_paths`).
    settings : DenseSettings or None, default None
        None for the defaults.
    engine : Engine or None, default None
        Where the depth maps are computed; None for this process.

    Returns
    -------
    DenseResult

    Raises
    ------
    DenseInputError
        A model with fewer than two views, or ``paths`` not one a view.
    ReconstructionError
        ``"no_fused_points"``: no depth passed the consistency check.
    """
    settings = settings or DenseSettings()
    engine = engine or LocalEngine()
    if len(model.names) < 2:
        raise DenseInputError("one_view", f"the model has {len(model.names)} image(s): dense "
                              "matching needs at least two views of the scene")
    if len(paths) != len(model.names):
        raise DenseInputError("missing_images", f"{len(paths)} photos for the model's "
                              f"{len(model.names)} images")
    scores = neighbour_scores(model)
    neighbours = choose_neighbours(scores, settings.neighbours)
    checks = choose_neighbours(scores, settings.fusion_views)
    ranges = []
    for v in range(len(model.names)):
        try:
            ranges.append(depth_range(model, v))
        except ValueError as exc:  # too few sparse points to bound its depths
            logger.warning("%s; it gets no depth map", exc)
            ranges.append(None)
            neighbours[v] = []
    cameras = [(Path(p), model.camera(v).K, model.camera(v).dist, model.R[v], model.t[v])
               for v, p in enumerate(paths)]
    lonely = [model.names[v] for v, nb in enumerate(neighbours)
              if not nb and ranges[v] is not None]
    if lonely:
        logger.warning("%d view(s) share no sparse point with another and get no depth "
                       "map: %s", len(lonely), ", ".join(lonely))
    tasks = [v for v, nb in enumerate(neighbours) if nb]
    t0 = time.perf_counter()
    computed = dict(zip(tasks, engine.map(
        view_depth, [(cameras[v], [cameras[u] for u in neighbours[v]], ranges[v],
                      settings.max_width, settings.sweep, settings.method) for v in tasks],
        label="depth maps")))
    t1 = time.perf_counter()
    views = [computed[v] for v in tasks]
    index = {v: i for i, v in enumerate(tasks)}
    check_views = [[index[u] for u in checks[v] if u in index] for v in tasks]
    voxel = settings.voxel_px * footprint(views) if any(v.valid_pixels for v in views) else 1.0
    cloud = fuse_depth_maps(views, voxel, settings.depth_tol, settings.reprojection_tol_px,
                            settings.min_agree, check_views)
    t2 = time.perf_counter()
    if cloud.num_points == 0:
        raise ReconstructionError(
            "no_fused_points", f"no depth of the {len(views)} depth maps is confirmed by "
            f"{settings.min_agree} other views: do the photos overlap, and does the model "
            "fit them?")
    logger.info("dense: %d fused points from %d depth maps (%.1f s, fusion %.1f s)",
                cloud.num_points, len(views), t1 - t0, t2 - t1)
    previews = [None if v not in computed else depth_preview(computed[v].depth)
                for v in range(len(model.names))]
    return DenseResult(cloud, previews, neighbours, ranges, voxel,
                       {"depth_maps": t1 - t0, "fusion": t2 - t1})
