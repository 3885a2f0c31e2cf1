"""The data of a multi-view reconstruction: the result (:class:`MultiViewReconstruction`)
and its cameras (:class:`CameraIntrinsics`).

The settings, the views' features and pairs and one model's data live in
:mod:`~scene3D.multiview.settings`, :mod:`~scene3D.multiview.view_data` and
:mod:`~scene3D.multiview.sfm_model`; their names are importable from here too.

Frames: each model has its own world frame (the camera frame of the first view of
its initial pair) and scale (that pair's baseline). Poses are world-to-camera,
``x_cam = R X + t``; pixels are those of the working images (OpenCV convention).
"""

from __future__ import annotations

import os
from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from ..geometry.conventions import FloatArray
from ..io.colmap import ColmapModel, colmap_model_from_views, model_for_photos
from ..io.export import all_or_nothing
from ..io.model_files import save_model
from ..optim.bundle import Observations
from .settings import FOCAL_SPREAD_LOG, SfMSettings, refutes_calibration  # noqa: F401
from .sfm_model import FocalEstimate, ModelCheck, SfMModel  # noqa: F401 - public here too
from .view_data import PairMatches, ViewFeatures  # noqa: F401 - public here too

if TYPE_CHECKING:
    from ..io.datasets import StrechaCamera


def reference_camera(view_camera: np.ndarray) -> int:
    """The camera of most views (the first such): the pixels the mapper works in.

    Parameters
    ----------
    view_camera : (V,) int ndarray
        The camera of each view.

    Returns
    -------
    int
    """
    return int(np.argmax(np.bincount(view_camera)))


@dataclass(frozen=True)
class CameraIntrinsics:
    """One camera of a reconstruction of photos from several cameras
    (:mod:`scene3D.multiview.cameras`).

    Attributes
    ----------
    K : (3, 3) float64
        Intrinsics of its working images (its focal length as the largest model found
        it, the principal point at the image centre).
    dist : (k,) float64
        OpenCV distortion coefficients about ``K`` (``(k1, k2, 0, 0)``; empty: none).
    image_size : (int, int)
        (width, height) of its working images.
    photo_size : (int, int)
        (width, height) of its photos as stored.
    name : str or None
        EXIF make and model, when known.
    prior_description : str
        Where its focal length started from.
    estimated : bool
        Whether the largest model holds a view of it (else ``K`` is the prior's).
    """

    K: FloatArray
    dist: FloatArray
    image_size: tuple[int, int]
    photo_size: tuple[int, int]
    name: str | None = None
    prior_description: str = ""
    estimated: bool = True


@dataclass(frozen=True)
class MultiViewReconstruction:
    """Cameras and points of a multi-view reconstruction: one model or several.

    The pose and point properties below are those of the largest model, ``models[0]``
    (:class:`SfMModel`); views that could not be joined to it are in further models
    when they connect among themselves, each in its own frame and scale.

    Conventions: world = the camera frame of the first view of the largest model's
    initial pair; poses world-to-camera, ``x_cam = R X + t``; arbitrary scale (the
    initial pair's unit baseline). ``V = len(names)`` views in the input order;
    pixels are those of the working images (``image_size``), OpenCV convention.

    Properties of the largest model:

    - ``registered`` : (V,) bool, which views it holds;
    - ``R`` : (V, 3, 3) float64, world-to-camera rotations (NaN for views not in it);
    - ``t`` : (V, 3) float64, world-to-camera translations (NaN likewise);
    - ``centers`` : (V, 3) float64, camera centres ``C = -R^T t`` in the world frame;
    - ``points3d`` : (P, 3) float64, points in the world frame;
    - ``colors`` : (P, 3) uint8, RGB colour of each point;
    - ``observations`` : :class:`scene3D.optim.bundle.Observations`, ``view`` (O,) input-view
      indices, ``point`` (O,) indices into ``points3d``, ``xy`` (O, 2) working pixels;
    - ``reprojection_rmse_px`` : float, RMS of the residuals' x and y components over
      the observations, with ``model_K(main)``.

    Attributes
    ----------
    names : tuple[str, ...]
        One per input view, in the input order (every per-view array follows it).
    K : (3, 3) float64
        Intrinsics of the working images: the calibration's, or without one those the
        largest model ended with (its focal length refined).
    image_size : tuple[int, int]
        (width, height) of the working images.
    models : tuple[SfMModel, ...]
        Largest first.
    unregistered_reasons : dict[str, str]
        Why each view in no model was left out.
    pair_selection : str
        How pairs were chosen (e.g. "retrieval (8 most similar views)").
    matched_pairs, verified_pairs : int
    timings_s : dict[str, float]
    calibration_source : str
        Where ``K``'s focal length comes from: ``"file"`` (a calibration), or
        ``FocalEstimate.source`` of the largest model.
    focal_refits : tuple[float, ...]
        With a calibration file: the factors by which its focal length was changed, in
        turn, because the largest model's views refuted it
        (``SfMSettings.max_focal_refits``); ``K`` carries their product. Empty when the
        calibration held.
    prior_description : str
        Without a calibration, where the prior came from ("EXIF FocalLengthIn35mmFilm
        32 mm", the default); empty with one.
    photo_size : tuple[int, int] or None
        (width, height) of the photos as stored, from which the working images were made
        (None: not known, taken as ``image_size``).
    dist : (k,) float64
        The photos' OpenCV distortion coefficients (empty: none), about ``K``: a
        calibration file's, removed from the images before features were found; or,
        without one, ``(k1, k2, 0, 0)`` of the lens the largest model found
        (:attr:`camera_model`), removed from the keypoints (the models' observations are
        the keypoints undistorted with it, so the models are exact pinhole models of
        those). A lens that moves no corner more than ``SfMSettings.lens_tolerance_px``
        from where no lens would leaves the keypoints as photographed (empty).
    camera_model : str
        ``"pinhole"`` (a calibration file's camera, or a pinhole camera asked for),
        ``"simple_radial"`` or ``"radial"`` (:mod:`scene3D.geometry.lens`).
    lens_passes : int
        How many times the views were reconstructed again with their keypoints
        undistorted (:mod:`scene3D.multiview.lens`).
    feature : str
        The detector asked for (``reconstruct_views``'s ``feature``).
    min_model_points : int
        ``SfMSettings.min_model_points``: a model with fewer points fails
        (:meth:`model_ok`).
    view_camera : (V,) int ndarray or None
        With photos of several cameras (:mod:`scene3D.multiview.cameras`): the camera of
        each view, an index into :attr:`cameras`; None for one camera, whose ``K``,
        ``dist``, ``image_size`` and ``photo_size`` are the attributes above (with
        several, those are the reference camera's, ``cameras[view_camera[v]]`` is view
        ``v``'s). The models' observations are in each view's own working pixels.
    cameras : tuple[CameraIntrinsics, ...]
        The cameras (empty for one camera: :meth:`view_intrinsics` gives it).
    verified_edges : tuple[tuple[int, int, int], ...]
        The verified pairs of the final pass as ``(a, b, inliers)``: input-order view indices
        ``a < b`` and the matches that fit the pair's essential matrix; sorted. Its length
        is :attr:`verified_pairs` (empty for a result made without the pipeline).
    """

    names: tuple[str, ...]
    K: FloatArray
    image_size: tuple[int, int]
    models: tuple[SfMModel, ...]
    unregistered_reasons: dict[str, str]
    pair_selection: str
    matched_pairs: int
    verified_pairs: int
    timings_s: dict[str, float] = field(default_factory=dict)
    calibration_source: str = "file"
    prior_description: str = ""
    focal_refits: tuple[float, ...] = ()
    photo_size: tuple[int, int] | None = None
    dist: FloatArray = field(default_factory=lambda: np.zeros(0))
    camera_model: str = "pinhole"
    lens_passes: int = 0
    feature: str = "SIFT"
    min_model_points: int = 10
    view_camera: np.ndarray | None = None
    cameras: tuple[CameraIntrinsics, ...] = ()
    verified_edges: tuple[tuple[int, int, int], ...] = ()

    @property
    def camera_list(self) -> tuple[CameraIntrinsics, ...]:
        """The cameras: :attr:`cameras`, or the one camera the attributes describe."""
        if self.cameras:
            return self.cameras
        return (CameraIntrinsics(np.asarray(self.K, np.float64), np.asarray(self.dist),
                                 tuple(self.image_size),
                                 tuple(self.photo_size or self.image_size),
                                 prior_description=self.prior_description),)

    @property
    def reference_camera(self) -> int:
        """The camera whose intrinsics are :attr:`K`, :attr:`dist` and :attr:`image_size`:
        the camera of most views (:func:`reference_camera`)."""
        return reference_camera(self.camera_of_view)

    @property
    def camera_of_view(self) -> np.ndarray:
        """The camera of each view ``(V,)``, an index into :attr:`camera_list`."""
        return (np.zeros(len(self.names), dtype=int) if self.view_camera is None
                else np.asarray(self.view_camera, dtype=int))

    def view_intrinsics(self, model: SfMModel | None = None) -> FloatArray:
        """The working intrinsics of each view ``(V, 3, 3)`` in ``model`` (default the
        largest): its camera's (:meth:`model_K` with one camera).

        Parameters
        ----------
        model : SfMModel or None, default None
            One of :attr:`models`.

        Returns
        -------
        (V, 3, 3) float64 ndarray
        """
        if self.view_camera is None:
            K = self.model_K(self.main if model is None else model)
            return np.broadcast_to(K, (len(self.names), 3, 3)).copy()
        model = self.main if model is None else model
        Ks = model.camera_K if model.camera_K is not None else np.stack(
            [c.K for c in self.cameras])
        return Ks[self.camera_of_view]

    @property
    def focal_refit_scale(self) -> float:
        """The product of :attr:`focal_refits`: ``K``'s focal length over the
        calibration's (1 when it held)."""
        return float(np.prod(self.focal_refits))

    @property
    def main(self) -> SfMModel:
        return self.models[0]

    @property
    def focal(self) -> FocalEstimate | None:
        """How the largest model found its focal length (None with a calibration file)."""
        return self.main.focal

    @property
    def focal_px_sigma(self) -> float | None:
        """Standard deviation of ``K``'s focal length in pixels (None with a calibration)."""
        return None if self.main.focal is None else self.main.focal.sigma_px

    def model_K(self, model: SfMModel) -> FloatArray:
        """The intrinsics of ``model`` (its own when it refined its focal length).

        Parameters
        ----------
        model : SfMModel
            One of :attr:`models`.

        Returns
        -------
        (3, 3) float64 ndarray
            Intrinsics of the working images.
        """
        return self.K if model.K is None else model.K

    @property
    def registered(self) -> np.ndarray:
        return self.main.registered

    @property
    def R(self) -> FloatArray:
        return self.main.R

    @property
    def t(self) -> FloatArray:
        return self.main.t

    @property
    def points3d(self) -> FloatArray:
        return self.main.points3d

    @property
    def colors(self) -> np.ndarray:
        return self.main.colors

    @property
    def observations(self) -> Observations:
        return self.main.observations

    @property
    def reprojection_rmse_px(self) -> float:
        return self.main.reprojection_rmse_px

    @property
    def centers(self) -> FloatArray:
        return self.main.centers

    @property
    def mean_track_length(self) -> float:
        return self.main.mean_track_length

    def point_errors_px(self) -> FloatArray:
        """Mean reprojection error of each point of the main model ``(P,)``."""
        return self.main.point_errors_px(self.model_K(self.main) if self.view_camera is None
                                         else self.view_intrinsics(self.main))

    def colmap_model(self, model: SfMModel | None = None, photos: bool = True) -> ColmapModel:
        """``model`` (default the largest) as a COLMAP model, one camera, image ids
        ``view + 1`` and point ids ``point + 1``.

        With ``photos`` (the default) its camera is that of the photos as stored
        (:attr:`photo_size`): the working intrinsics scaled back, the photos' distortion
        (OPENCV) when they had some, and the observations where they lie in the photos
        (:func:`scene3D.io.colmap.model_for_photos`), so that tools which open the
        photos (COLMAP, pycolmap, Gaussian-splatting trainers) find the points where
        the model says. Without, the model of the undistorted working images (PINHOLE).

        After a focal refit (:attr:`focal_refits`) of distorted photos the distortion
        is put back with the refitted focal length, an approximation of what the
        undistortion with the calibration's did.

        Parameters
        ----------
        model : SfMModel or None, default None
            One of :attr:`models`; None for the largest.
        photos : bool, default True
            The camera of the photos as stored, rather than of the working images.

        Returns
        -------
        ColmapModel
            World-to-camera poses (``x_cam = R X + t``).
        """
        model = self.main if model is None else model
        obs = model.observations
        if self.view_camera is not None:  # one camera per camera of the photos
            Ks = model.camera_K if model.camera_K is not None else np.stack(
                [c.K for c in self.cameras])
            working = colmap_model_from_views(
                self.names, Ks, [c.image_size for c in self.cameras], model.registered,
                model.R, model.t, model.points3d, model.colors, obs.view, obs.point, obs.xy,
                view_camera=self.view_camera)
            if not photos:
                return working
            return model_for_photos(working, {c + 1: cam.photo_size for c, cam in
                                              enumerate(self.cameras)},
                                    {c + 1: cam.dist for c, cam in enumerate(self.cameras)})
        working = colmap_model_from_views(self.names, self.model_K(model), self.image_size,
                                          model.registered, model.R, model.t,
                                          model.points3d, model.colors, obs.view, obs.point,
                                          obs.xy)
        if not photos:
            return working
        return model_for_photos(working, self.photo_size or self.image_size, self.dist)

    def save(self, folder: str | os.PathLike,
             images: str | os.PathLike | Mapping[str, str | os.PathLike] | None = None,
             undistort: bool = False) -> list[Path]:
        """Write every model's files as ``reconstruct-views`` does, all or none: the
        largest in ``folder``, further ones in ``folder/model-1``, ...; in each
        ``points.ply``, ``cameras.json`` and ``colmap/`` at the photos' size
        (:meth:`colmap_model`, :func:`scene3D.io.model_files.save_model`) and, given the
        photos (their folder, or each one's path by its name), ``transforms.json``;
        with ``undistort`` too, as ``--export nerfstudio --undistort``, the photos
        undistorted into ``folder/undistorted`` and named by the ``transforms.json``
        files with pinhole cameras. Returns the paths written.

        Parameters
        ----------
        folder : str or os.PathLike
            Target folder (created if needed).
        images : path, mapping of str to path, or None, default None
            The photos' folder, or each photo's path by name; None for no
            ``transforms.json``.
        undistort : bool, default False
            With ``images``: write them undistorted (PNG) for ``transforms.json``.

        Returns
        -------
        list of Path
        """
        from ..io.undistorted import UNDISTORTED_FOLDER

        folder = Path(folder)
        written: list[Path] = []
        with all_or_nothing():
            for m, model in enumerate(self.models):
                written += save_model(folder if m == 0 else folder / f"model-{m}",
                                      self.colmap_model(model), images, undistort=undistort,
                                      undistorted_folder=folder / UNDISTORTED_FOLDER)
        return written

    @property
    def model_of_view(self) -> np.ndarray:
        """Index of the model holding each view, -1 for none ``(V,)``."""
        out = np.full(len(self.names), -1, dtype=int)
        for m, model in reversed(list(enumerate(self.models))):
            out[model.registered] = m
        return out

    @property
    def unregistered(self) -> tuple[str, ...]:
        """Views in no model."""
        return tuple(n for n, m in zip(self.names, self.model_of_view) if m < 0)

    @property
    def self_calibrated(self) -> bool:
        """The focal length was found from the photos (no calibration file)."""
        return self.calibration_source != "file"

    def model_ok(self, model: SfMModel) -> bool:
        """``model`` passed its consistency check and has ``min_model_points`` points.

        Parameters
        ----------
        model : SfMModel
            One of :attr:`models`.

        Returns
        -------
        bool
        """
        return model.check.ok and len(model.points3d) >= self.min_model_points

    @property
    def consistent(self) -> bool:
        """Every model passed the consistency check (whatever its number of points)."""
        return all(model.check.ok for model in self.models)

    @property
    def thin_models(self) -> tuple[int, ...]:
        """The indices of the models with fewer than ``min_model_points`` points."""
        return tuple(m for m, model in enumerate(self.models)
                     if len(model.points3d) < self.min_model_points)

    @property
    def ok(self) -> bool:
        """Every model passed the consistency check and has ``min_model_points`` points:
        the result that ``scene3d reconstruct-views`` calls a success."""
        return all(self.model_ok(model) for model in self.models)

    def to_dict(self, camera: str | None = None,
                ground_truth: list[StrechaCamera] | None = None) -> dict:
        """The summary as plain data (:func:`scene3D.multiview.summary.reconstruction_summary`).

        Parameters
        ----------
        camera : str, optional
            The photos' camera, for a self-calibration
            (:attr:`scene3D.geometry.intrinsics_prior.FocalPrior.camera_name`).
        ground_truth : list of StrechaCamera, optional
            One camera per view (:func:`scene3D.io.datasets.read_strecha_cameras`): each
            model's camera errors are added.

        Returns
        -------
        dict
            What ``scene3d reconstruct-views`` writes as ``reconstruction.json``, arrays as
            numpy arrays (:func:`scene3D.io.export.write_json` writes them).
        """
        from .summary import reconstruction_summary

        return reconstruction_summary(self, camera, ground_truth)
