"""One connected model of a multi-view reconstruction: its cameras and points
(:class:`SfMModel`), what its consistency check found (:class:`ModelCheck`) and, for photos
without a calibration, its focal length (:class:`FocalEstimate`).

Frames: each model has its own world frame (the camera frame of the first view of
its initial pair) and scale (that pair's baseline). Poses are world-to-camera,
``x_cam = R X + t``; pixels are those of the working images (OpenCV convention).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..geometry.conventions import FloatArray, camera_centers
from ..optim.bundle import Observations, reprojection_residuals


@dataclass(frozen=True)
class ModelCheck:
    """What the final consistency check found (:func:`scene3D.multiview.checks.check_model`).

    Attributes
    ----------
    pairs_checked : int
        Verified pairs with both views in the model.
    inconsistent_pairs : tuple[tuple[int, int, float], ...]
        ``(i, j, median Sampson distance px)`` of the pairs whose matches contradict the
        model's cameras.
    suspect_views : tuple[int, ...]
        Views whose pose contradicts most of their pair geometry (weighted by inliers),
        or that only inconsistent pairs tie to the rest of the model (a fold).
    focal_scale, focal_scale_sigma_log : float
        With a calibration file, models of three views or more: the focal length the
        model's observations call for (one shared by every view, adjusted with the
        cameras and points; :func:`scene3D.optim.bundle.bundle_adjust_focal`), as a factor of
        the calibration's, and the standard deviation of its log. 1 and inf when not
        tested.
    focal_mismatch : bool
        That focal length refutes the calibration's
        (:func:`scene3D.multiview.settings.refutes_calibration`).
    """

    pairs_checked: int
    inconsistent_pairs: tuple[tuple[int, int, float], ...] = ()
    suspect_views: tuple[int, ...] = ()
    focal_scale: float = 1.0
    focal_scale_sigma_log: float = float("inf")
    focal_mismatch: bool = False

    @property
    def ok(self) -> bool:
        return not self.suspect_views and not self.focal_mismatch


@dataclass(frozen=True)
class FocalEstimate:
    """The focal length of photos without a calibration file, as a model found it
    (:mod:`scene3D.multiview.focal`).

    Attributes
    ----------
    focal_px : float
        The focal length of the model's ``K`` (working images).
    sigma_px : float
        Its standard deviation: the adjustment's (the noise, cameras and points
        marginalised, the prior included), the guessed principal point's share and the
        spread over the views combined; the prior's when the views did not determine it.
    source : str
        ``"exif+refined"`` / ``"prior+refined"`` (the views determined it), or
        ``"exif"`` / ``"prior"`` (they did not: the start's value was kept), or
        ``"inherited"``: a further model of fewer than ``FocalSettings.min_views`` views,
        which keeps the focal length of the model built before it.
    determined : bool
        The views alone know ``log f`` at least as well as the prior does.
    adjustment_sigma_log : float
        Standard deviation of ``log f`` from the adjustment, the principal point known.
    principal_point_sigma_log : float
        How far ``log f`` moves with the principal point off by
        ``FocalSettings.principal_point_sigma`` of the longer side.
    jackknife_sigma_log : float
        How far ``log f`` spreads over the views: the grouped jackknife of the model
        adjusted again without each quarter of its views (each half below eight)
        (:meth:`scene3D.multiview.state.GrowingModel.focal_jackknife_sigma_log`; 0 for a
        model of fewer than four views).
    data_focal_px, data_sigma_log : float
        What the views call for (the adjusted value) and how well they alone know it
        (the prior's share taken out, the principal point's added; inf: not at all).
    prior_focal_px, prior_sigma_log : float
        The prior (EXIF or the default, at the working size).
    start_focal_px : float
        Where the mapping started: the start pair's self-calibration (or the prior).
    start_pair : tuple[int, int] or None
        The pair self-calibrated (view indices of the mapper), None when none was.
    warnings : tuple[str, ...]
    trusted : bool
        The focal length is known to ``FocalSettings.max_trusted_sigma_log`` from the
        views, and the views do not contradict an EXIF value.
    """

    focal_px: float
    sigma_px: float
    source: str
    determined: bool
    adjustment_sigma_log: float
    principal_point_sigma_log: float
    data_focal_px: float
    data_sigma_log: float
    prior_focal_px: float
    prior_sigma_log: float
    start_focal_px: float
    start_pair: tuple[int, int] | None = None
    warnings: tuple[str, ...] = ()
    trusted: bool = True
    jackknife_sigma_log: float = 0.0


@dataclass(frozen=True)
class SfMModel:
    """One connected reconstruction: some views' cameras and the points they see.

    Conventions: the model's world is the camera frame of the first view of its
    initial pair (that camera is ``[I | 0]``); poses are world-to-camera,
    ``x_cam = R X + t``; the scale is arbitrary (set by the initial pair's unit
    baseline). ``V`` is the number of input views, in the input order; pixels are
    those of the working images (OpenCV convention).

    Attributes
    ----------
    registered : (V,) bool
        Which of all input views are in this model.
    R : (V, 3, 3) float64
        World-to-camera rotations (NaN for views not in the model).
    t : (V, 3) float64
        World-to-camera translations, in each camera's frame (NaN for views not in it).
    points3d : (P, 3) float64
        Points in the model's world frame.
    colors : (P, 3) uint8
        RGB colour of each point, from its first observation.
    observations : Observations
        Every measurement kept: ``view`` (O,) input-view indices, ``point`` (O,)
        indices into ``points3d``, ``xy`` (O, 2) working-image pixels.
    reprojection_rmse_px : float
        Root mean square of the reprojection residuals' x and y components over all
        observations (unweighted), with the model's intrinsics; NaN without any.
    check : ModelCheck
    K : (3, 3) float64 or None
        The intrinsics this model was adjusted with, when it refined its focal length
        (photos without a calibration file); None: the reconstruction's ``K``.
    focal : FocalEstimate or None
        How its focal length was found (None with a calibration file).
    camera_scale : (C,) float64 or None
        With several cameras (:mod:`scene3D.multiview.cameras`): the factor by which
        each camera's keypoints were rescaled about the principal point while the model
        grew (its focal length found by the model, 1: as given); None with one camera.
    camera_K : (C, 3, 3) float64 or None
        With several cameras, each camera's working intrinsics in this model (its
        observations are in each view's own pixels); None with one camera.

    The property ``centers`` ``(V, 3)`` gives the camera centres ``C = -R^T t`` in the
    world frame (NaN for views not in the model).
    """

    registered: np.ndarray
    R: FloatArray
    t: FloatArray
    points3d: FloatArray
    colors: np.ndarray
    observations: Observations
    reprojection_rmse_px: float
    check: ModelCheck
    K: FloatArray | None = None
    focal: FocalEstimate | None = None
    camera_scale: FloatArray | None = None
    camera_K: FloatArray | None = None

    @property
    def centers(self) -> FloatArray:
        """Camera centres ``C = -R^T t`` in world coordinates ``(V, 3)``."""
        return camera_centers(self.R, self.t)

    @property
    def views(self) -> tuple[int, ...]:
        return tuple(int(v) for v in np.flatnonzero(self.registered))

    @property
    def mean_track_length(self) -> float:
        return float(len(self.observations.view) / max(len(self.points3d), 1))

    def point_errors_px(self, K: FloatArray) -> FloatArray:
        """Mean reprojection error of each point over its observations ``(P,)``.

        Parameters
        ----------
        K : (3, 3) or (V, 3, 3) ndarray
            The model's intrinsics (:meth:`MultiViewReconstruction.model_K`), or each
            view's (:meth:`MultiViewReconstruction.view_intrinsics`).

        Returns
        -------
        (P,) float64 ndarray
            Pixels; 0 for a point without observations.
        """
        K = np.asarray(K, np.float64)
        obs = self.observations
        if K.ndim == 3:
            cam = np.einsum("oij,oj->oi", self.R[obs.view], self.points3d[obs.point])
            pix = np.einsum("oij,oj->oi", K[obs.view], cam + self.t[obs.view])
            err = np.linalg.norm(pix[:, :2] / pix[:, 2:3] - obs.xy, axis=1)
        else:
            err = np.linalg.norm(reprojection_residuals(self.R, self.t, self.points3d, obs, K),
                                 axis=1)
        sums = np.bincount(self.observations.point, err, minlength=len(self.points3d))
        counts = np.bincount(self.observations.point, minlength=len(self.points3d))
        return sums / np.maximum(counts, 1)
