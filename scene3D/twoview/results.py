"""The two-view pipeline's settings and results (see :mod:`scene3D.twoview`)."""

from __future__ import annotations

import math
import os
from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
from numpy.typing import ArrayLike

from ..geometry.conventions import FloatArray, is_real_number, is_whole_number
from ..io.colmap import ColmapModel, colmap_model_from_views, model_for_photos
from ..io.export import all_or_nothing
from ..io.model_files import save_model
from ..optim.uncertainty import PoseUncertainty, tangent_basis
from .measurements import TwoViewChecks, TwoViewFocal, TwoViewUncertainty


@dataclass(frozen=True)
class TwoViewSettings:
    """Thresholds of the two-view pipeline (defaults suit the book's 768 px images).

    Attributes
    ----------
    threshold_px : float
        Robust-estimation inlier threshold for F, E and H, in pixels (> 0). The local
        optimisation of E raises it, at most twofold, when the matches are noisier
        than it assumes (:func:`scene3D.twoview.essential_fit.inlier_threshold_px`).
    max_starts : int
        Most robust estimations of E (each locally optimised); the best is kept
        once two starts agree on it (:func:`scene3D.twoview.essential_fit.fit_essential`).
        1 gives a single start, as plain OpenCV does (>= 1).
    restart_agreement_deg : float
        When no pose was found twice, the result is still trusted if every start's
        optimum lies within this angle of the best (distinct optima, one pose to
        that accuracy), or within the region the pose's covariance allows
        (:func:`scene3D.twoview.rival_chi2`: the sigmas already say it); beyond
        both the result is marked untrusted: a covariance describes one optimum
        and cannot see the others. When the best was found twice, a rival outside
        that region counts from ``uncertainty_limit_deg`` on. 0 to 180.
    min_matches, min_inliers, min_points : int
        Below these counts the pair is refused (at least 5, 5 and 1: five
        correspondences determine an essential matrix).
    min_point_parallax_deg : float
        Points seen under a smaller angle are dropped (their depth is unreliable),
        unless that leaves fewer than ``min_points`` (a small baseline): then every
        point in front of both cameras is kept, with its depth uncertainty (0 to 180).
    max_reprojection_px : float
        Points reprojecting worse than this in either view are dropped (> 0; ``inf``
        keeps them all).
    planar_ratio : float
        Homography inliers / essential inliers above which the pair is checked for
        the planar ambiguity (:func:`scene3D.twoview.degeneracy.off_plane_evidence`; 0 to 1).
    min_off_plane_matches : int
        A (nearly) planar pair is refused unless at least this many matches off the
        plane rule out the other pose that the plane allows (>= 0).
    uncertainty_limit_deg, uncertainty_sigmas : float, float
        The purpose: a pose is untrusted when ``uncertainty_sigmas`` standard
        deviations of its rotation or of its translation direction
        (``rotation_sigma_deg``, ``translation_sigma_deg`` of the result) exceed
        ``uncertainty_limit_deg``. The default, 3 sigma within 2 deg, keeps the
        direction within 2 deg with at least 98.9 % probability. Both > 0; the limit
        may be ``inf`` (no limit), the sigmas not. Twice the limit is how far the pose
        refined on the dense flow (``max_flow_gain``) or with a radial lens distortion
        (:func:`scene3D.twoview.trust.distortion_warning`) may lie before the pose is
        doubted.
    max_noise_cut_share : float
        The pose is untrusted when the inlier threshold cuts off more than this share
        of the matches that fit it (:func:`scene3D.optim.uncertainty.truncated_noise`: the
        matches are noisier than the threshold, at most
        :data:`scene3D.twoview.essential_fit.MAX_THRESHOLD_GROWTH` times ``threshold_px``, can
        hold): the pose then rests on the matches that happen to fit best, which
        biases it, and the covariance's allowance for the cut no longer makes up
        for it (docs/benchmarks.md#noise-the-threshold-cut-off). 0 to 1.
    max_rotation_share : float
        The pose is untrusted when a rotation alone explains more than this share of
        the inliers (within three noise standard deviations;
        :func:`scene3D.twoview.degeneracy.motion_model_choice`): most matches show no
        parallax, and the translation rests on the others, which a moving object
        would explain as well as a camera that moved (a still camera and a chessboard
        moved by hand: docs/trust.md#flagged-pairs). 0 to 1.
    trusted_inliers : int
        Fewer inliers leave the pose untrusted whatever its covariance says: a
        covariance estimated from few residuals is itself uncertain, and random
        matches can agree on a wrong pose by chance (a few dozen of them among a
        few hundred; ``tests/test_twoview.py``). For the same reason the robust fit
        tests its last refinement against its covariance only above this count
        (``shift_test_min_inliers`` of :func:`scene3D.twoview.essential_fit.fit_essential`).
        >= 0.
    trusted_inlier_ratio, trusted_parallax_deg, planar_warning_ratio : float
        Not verdicts: when the uncertainty is too large, the warning names the
        likely causes, an inlier share of the matches below ``trusted_inlier_ratio``
        (wide baseline, repeated texture), a median parallax below
        ``trusted_parallax_deg`` (short baseline), a homography explaining more
        than ``planar_warning_ratio`` of the inliers (a nearly planar scene). All
        three 0 to 1 (the angle 0 to 180).
    max_behind_share : float
        The pose is untrusted when more than this share of its inliers triangulate
        behind a camera, by more than the noise explains and at the scene's parallax
        (:func:`scene3D.geometry.triangulation.behind_at_scene_parallax`; ``behind_share`` of
        the result). Each is a wrong match that happens to lie near its epipolar line
        (or a point of an object that moved), and a random match within 1 px of a
        pose's epipolar line lands so about a third of the time, so a
        fifth behind means that about half of the inliers or more are wrong: the pose
        itself may rest on wrong matches that agree (repeated texture), which its
        covariance cannot see. Far points that a focal length a few percent off or an
        uncorrected distortion pushes across infinity meet at angles far below the
        scene's and do not count (docs/benchmarks.md#inliers-behind-the-cameras). 0 to 1
        (1: never flagged).
    max_focal_mismatch, focal_mismatch_sigmas : float, float
        The result is marked untrusted when the matches call for a focal length more
        than ``1 + max_focal_mismatch`` times larger or smaller than the
        calibration's, by more than ``focal_mismatch_sigmas`` standard deviations
        (:func:`scene3D.twoview.focal_fit.fit_focal_scale`): the calibration is probably
        for another camera, lens or zoom, and the pose is off by degrees. The same limits
        hold for image 2's focal length against image 1's
        (:func:`scene3D.twoview.focal_fit.fit_focal_ratio`): two zoom settings, or one photo
        cropped or resized, with one calibration. Three
        standard deviations of the sandwich estimate: with the true K no right pose of
        the Strecha scenes is flagged for its focal length
        (docs/benchmarks.md#the-focal-length-check). Both
        >= 0 (``max_focal_mismatch`` may be ``inf``: never flagged).
    max_flow_gain : float
        A pose that passed every other check, reconstructed with both images at hand
        (:func:`scene3D.twoview.check_against_flow`), is marked untrusted when the pose
        refined on the dense optical flow between the images puts more than this share
        of the flow's textured pixels more within
        :data:`scene3D.twoview.flow_check.FLOW_BAND_PX` of its epipolar lines
        (:func:`scene3D.twoview.flow_check.check_pose_against_flow`) and lies at least half
        ``uncertainty_limit_deg`` away: sparse matches on repeated texture agreed on
        a wrong pose that the flow does not follow; the default lies between the gains
        of right and of wrong poses on the Strecha scenes
        (docs/benchmarks.md#the-dense-flow-check). Half the limit: a pose nearer the
        flow's than that is near enough for the purpose, whatever the flow prefers.
        Whatever the gain, a flow's pose more than twice ``uncertainty_limit_deg`` away
        is a doubt too (docs/trust.md#the-dense-flow-check). 0 to 1 (1: not checked,
        which saves the flow's time).
    check_distortion : bool
        Refine a pose that passed every other check once more with one radial lens
        distortion, and doubt it when that moves it more than twice
        ``uncertainty_limit_deg`` (:func:`scene3D.twoview.trust.distortion_warning`): a
        calibration that leaves out the lens's distortion gave trusted poses degrees
        off (docs/trust.md#a-lens-distortion-the-calibration-leaves-out). The
        self-calibration of photos without a calibration
        file turns it off: its fitted focal length soaks up most of a distortion, which
        leaves the check nearly blind there (docs/trust.md).
    bundle_adjust : bool
        Finish with a two-view bundle adjustment of pose and points
        (:func:`scene3D.optim.bundle_two_view.bundle_adjust_two_view`) with the same Cauchy
        loss as the local optimisation. Off by default: on the benchmark pairs it
        moves the poses by hundredths of a degree at most, closer to the truth on some
        and further on others, and costs time
        (docs/benchmarks.md#two-view-bundle-adjustment).

    Raises
    ------
    ValueError
        When a field is outside its range (NaN never is in one), or of the wrong type.
    """

    threshold_px: float = 1.0
    max_starts: int = 16
    restart_agreement_deg: float = 0.5
    min_matches: int = 20
    min_inliers: int = 15
    min_points: int = 10
    min_point_parallax_deg: float = 0.5
    max_reprojection_px: float = 2.0
    planar_ratio: float = 0.95
    min_off_plane_matches: int = 10
    uncertainty_limit_deg: float = 2.0
    uncertainty_sigmas: float = 3.0
    max_rotation_share: float = 0.5
    trusted_inliers: int = 50
    trusted_inlier_ratio: float = 0.25
    trusted_parallax_deg: float = 2.0
    planar_warning_ratio: float = 0.85
    max_noise_cut_share: float = 0.1
    max_behind_share: float = 0.2
    max_focal_mismatch: float = 0.15
    focal_mismatch_sigmas: float = 3.0
    max_flow_gain: float = 0.1
    check_distortion: bool = True
    bundle_adjust: bool = False

    def __post_init__(self) -> None:
        for name, (low, high, low_open, inf_ok) in _REAL_RANGES.items():
            value = getattr(self, name)
            if not _in_range(value, low, high, low_open, inf_ok):
                bound = f"{'>' if low_open else '>='} {low:g}"
                allowed = (f"a number from {low:g} to {high:g}" if high < math.inf else
                           f"a number {bound} or inf" if inf_ok else f"a finite number {bound}")
                raise ValueError(f"TwoViewSettings.{name} must be {allowed}, got {value!r}")
        for name, low in _INT_MINIMA.items():
            value = getattr(self, name)
            if not (is_whole_number(value) and value >= low):
                raise ValueError(f"TwoViewSettings.{name} must be an integer >= {low}, "
                                 f"got {value!r}")
        for name in ("check_distortion", "bundle_adjust"):
            if not isinstance(getattr(self, name), (bool, np.bool_)):
                raise ValueError(f"TwoViewSettings.{name} must be True or False, got "
                                 f"{getattr(self, name)!r}")


def _in_range(value: object, low: float, high: float, low_open: bool, inf_ok: bool) -> bool:
    """True for a real number (not a bool, not NaN) within ``low..high``."""
    if not is_real_number(value) or math.isnan(value):
        return False
    if math.isinf(value) and not inf_ok:
        return False
    return (value > low if low_open else value >= low) and value <= high


#: Allowed ranges of the real fields of :class:`TwoViewSettings`:
#: ``(low, high, low excluded, inf allowed)``.
_REAL_RANGES: dict[str, tuple[float, float, bool, bool]] = {
    "threshold_px": (0.0, math.inf, True, False),
    "restart_agreement_deg": (0.0, 180.0, False, False),
    "min_point_parallax_deg": (0.0, 180.0, False, False),
    "max_reprojection_px": (0.0, math.inf, True, True),
    "planar_ratio": (0.0, 1.0, False, False),
    "uncertainty_limit_deg": (0.0, math.inf, True, True),
    "uncertainty_sigmas": (0.0, math.inf, True, False),
    "max_rotation_share": (0.0, 1.0, False, False),
    "trusted_inlier_ratio": (0.0, 1.0, False, False),
    "trusted_parallax_deg": (0.0, 180.0, False, False),
    "planar_warning_ratio": (0.0, 1.0, False, False),
    "max_noise_cut_share": (0.0, 1.0, False, False),
    "max_behind_share": (0.0, 1.0, False, False),
    "max_focal_mismatch": (0.0, math.inf, False, True),
    "focal_mismatch_sigmas": (0.0, math.inf, False, False),
    "max_flow_gain": (0.0, 1.0, False, False),
}

#: Smallest values of the integer fields of :class:`TwoViewSettings`.
_INT_MINIMA: dict[str, int] = {
    "max_starts": 1, "min_matches": 5, "min_inliers": 5, "min_points": 1,
    "min_off_plane_matches": 0, "trusted_inliers": 0,
}


def _forward(group: str, name: str) -> property:
    """A read-only attribute that reads ``getattr(self.<group>, name)``."""
    def get(self: TwoViewGeometry) -> object:
        return getattr(getattr(self, group), name)
    get.__doc__ = (f"``{group}.{name}`` "
                   f"(:class:`scene3D.twoview.measurements.{_GROUP_TYPES[group]}`).")
    return property(get)


#: The type of each group of :class:`TwoViewGeometry`, for the forwarding attributes' docs.
_GROUP_TYPES = {"focal": "TwoViewFocal", "uncertainty": "TwoViewUncertainty",
                "checks": "TwoViewChecks"}


@dataclass(frozen=True)
class TwoViewGeometry:
    """Pose and structure of a pair, as found from its correspondences alone.

    The pose, the points and the matches are attributes of their own; what the stages
    measured about them comes in three groups: ``focal`` (the focal lengths the inliers
    call for), ``uncertainty`` (the pose's covariance, the keypoint noise and the
    points' depth sigmas) and ``checks`` (what the trust checks measured). Each of
    their attributes is readable here too under its former flat name (read-only):
    ``focal_scale``, ``focal_scale_sigma``, ``focal_ratio``, ``focal_ratio_sigma``
    (``focal.scale`` ...); ``pose_covariance``, ``rotation_sigma_deg``,
    ``translation_sigma_deg``, ``noise_sigma_px``, ``noise_cut_share``,
    ``depth_sigmas``; ``homography_inlier_ratio``, ``robust_starts``,
    ``robust_spread_deg``, ``behind_share``, ``flow_gain``, ``distortion_k``,
    ``distortion_pose_shift_deg``. A copy with other values replaces the group:
    ``dataclasses.replace(g, checks=dataclasses.replace(g.checks, flow_gain=0.0))``.

    Attributes
    ----------
    R : (3, 3) float64
        ``R_cam2_from_cam1``.
    t : (3,) float64
        Unit translation, ``x_cam2 = R @ x_cam1 + t`` (scale unknown).
    points3d : (N, 3) float64
        Triangulated points in the camera-1 frame, in units of the baseline.
    pts1, pts2 : (N, 2) float64
        Pixels of the kept points in the working images.
    K : (3, 3) float64
        Intrinsics of the working images.
    F, E : (3, 3) float64
        Fundamental (pixels, ``F = K^-T E K^-1``) and essential matrices, unit norm.
    num_matches, num_inliers : int
        Putative matches, and inliers of the essential matrix.
    reprojection_rmse_px : float
        RMS reprojection error of ``points3d`` over both views.
    median_parallax_deg : float
        Median triangulation angle of the kept points.
    trusted : bool
        False when a check raised a doubt; see ``warnings``.
    warnings : tuple[str, ...]
        Human-readable doubts about the result.
    inlier_pts1, inlier_pts2 : (M, 2) float64
        All essential-matrix inliers (before triangulation filters).
    refinement_s : float
        Seconds spent refining the pose (and bundle adjusting, if asked).
    focal : TwoViewFocal
        The focal length (scale of the calibration's) and the ratio of image 2's to
        image 1's that the inliers call for, with their standard deviations.
    uncertainty : TwoViewUncertainty
        The pose's ``(5, 5)`` covariance (rotation in the camera-2 frame, the direction
        of ``t`` in its tangent basis) and its sigmas, the keypoint noise, the
        ``(N,)`` depth sigmas of ``points3d`` in camera 1.
    checks : TwoViewChecks
        The homography ratio, the robust starts and their spread, the share of inliers
        behind a camera, the dense flow's gain, the radial distortion and its pose shift.
    """

    R: FloatArray
    t: FloatArray
    points3d: FloatArray
    pts1: FloatArray
    pts2: FloatArray
    K: FloatArray
    F: FloatArray
    E: FloatArray
    num_matches: int
    num_inliers: int
    reprojection_rmse_px: float
    median_parallax_deg: float
    trusted: bool
    warnings: tuple[str, ...]
    inlier_pts1: FloatArray
    inlier_pts2: FloatArray
    refinement_s: float = 0.0
    focal: TwoViewFocal = field(default_factory=TwoViewFocal)
    uncertainty: TwoViewUncertainty = field(default_factory=TwoViewUncertainty)
    checks: TwoViewChecks = field(default_factory=TwoViewChecks)

    focal_scale = _forward("focal", "scale")
    focal_scale_sigma = _forward("focal", "scale_sigma")
    focal_ratio = _forward("focal", "ratio")
    focal_ratio_sigma = _forward("focal", "ratio_sigma")
    pose_covariance = _forward("uncertainty", "pose_covariance")
    rotation_sigma_deg = _forward("uncertainty", "rotation_sigma_deg")
    translation_sigma_deg = _forward("uncertainty", "translation_sigma_deg")
    noise_sigma_px = _forward("uncertainty", "noise_sigma_px")
    noise_cut_share = _forward("uncertainty", "noise_cut_share")
    depth_sigmas = _forward("uncertainty", "depth_sigmas")
    homography_inlier_ratio = _forward("checks", "homography_inlier_ratio")
    robust_starts = _forward("checks", "robust_starts")
    robust_spread_deg = _forward("checks", "robust_spread_deg")
    behind_share = _forward("checks", "behind_share")
    flow_gain = _forward("checks", "flow_gain")
    distortion_k = _forward("checks", "distortion_k")
    distortion_pose_shift_deg = _forward("checks", "distortion_pose_shift_deg")

    @property
    def pose_uncertainty(self) -> PoseUncertainty:
        """The covariance with the tangent basis of ``t`` it refers to."""
        return PoseUncertainty(self.pose_covariance, tangent_basis(self.t), self.noise_sigma_px,
                               self.noise_cut_share)


@dataclass(frozen=True, kw_only=True)
class TwoViewReconstruction(TwoViewGeometry):
    """The result of reconstructing one image pair: :class:`TwoViewGeometry` plus

    Attributes
    ----------
    colors : (N, 3) uint8
        RGB colour of each point, sampled from image 1.
    feature : str
        The detector that actually ran.
    timings_s : dict[str, float]
        Seconds per stage.
    """

    colors: np.ndarray
    feature: str
    timings_s: dict[str, float] = field(default_factory=dict)

    @property
    def num_points(self) -> int:
        return len(self.points3d)

    @property
    def Rt1(self) -> FloatArray:
        """``[I | 0]``, the book's camera-1 matrix (3, 4)."""
        return np.hstack([np.eye(3), np.zeros((3, 1))])

    @property
    def Rt2(self) -> FloatArray:
        """``[R | t]``, the book's camera-2 matrix (3, 4)."""
        return np.hstack([self.R, self.t.reshape(3, 1)])

    def colmap_model(self, image_size: tuple[int, int],
                     names: tuple[str, str] = ("image1", "image2"),
                     photo_size: tuple[int, int] | None = None,
                     dist: ArrayLike | None = None) -> ColmapModel:
        """The pair as a COLMAP model: camera 1 ``[I | 0]`` (the world), camera 2
        ``[R | t]``, every point seen by both at ``pts1`` and ``pts2``.

        ``image_size`` (width, height) is that of the working images ``K`` is for; with
        ``photo_size`` the model is that of the photos they came from (``K`` scaled back,
        ``dist`` put back: :func:`scene3D.io.colmap.model_for_photos`).

        Parameters
        ----------
        image_size : (int, int)
            ``(width, height)`` of the working images (px).
        names : (str, str), default ("image1", "image2")
            The two images' names.
        photo_size : (int, int) or None, default None
            ``(width, height)`` of the photos; None for the working images' model.
        dist : array_like or None, default None
            The photos' OpenCV distortion coefficients.

        Returns
        -------
        ColmapModel
        """
        n = len(self.points3d)
        model = colmap_model_from_views(
            list(names), self.K, image_size, np.ones(2, bool),
            np.stack([np.eye(3), self.R]), np.stack([np.zeros(3), self.t]), self.points3d,
            self.colors, np.repeat([0, 1], n), np.tile(np.arange(n), 2),
            np.concatenate([self.pts1, self.pts2]))
        if photo_size is None:
            return model
        return model_for_photos(model, photo_size, dist)

    def save(self, folder: str | os.PathLike, image_size: tuple[int, int],
             names: tuple[str, str] = ("image1", "image2"),
             photo_size: tuple[int, int] | None = None, dist: ArrayLike | None = None,
             images: str | os.PathLike | Mapping[str, str | os.PathLike] | None = None,
             undistort: bool = False) -> list[Path]:
        """Write the pair's files into ``folder``, all or none: ``point_cloud.ply`` (as
        ``chapter4.py`` names it), ``cameras.json`` and ``colmap/`` of
        :meth:`colmap_model` and, given the images (their folder, or each one's path by
        its name), ``transforms.json`` (:func:`scene3D.io.model_files.save_model`);
        with ``undistort`` too, the images undistorted into ``folder/undistorted`` and
        named by ``transforms.json`` with pinhole cameras. Returns the paths written.

        Parameters
        ----------
        folder : str or os.PathLike
            Target folder (created if needed).
        image_size : (int, int)
            ``(width, height)`` of the working images (px).
        names : (str, str), default ("image1", "image2")
            The two images' names.
        photo_size : (int, int) or None, default None
            ``(width, height)`` of the photos; None to write the working images' model.
        dist : array_like or None, default None
            The photos' OpenCV distortion coefficients.
        images : path, mapping of str to path, or None, default None
            The images' folder, or each image's path by name; None for no
            ``transforms.json``.
        undistort : bool, default False
            With ``images``: write them undistorted (PNG) for ``transforms.json``.

        Returns
        -------
        list of Path
        """
        with all_or_nothing():
            return save_model(folder, self.colmap_model(image_size, names, photo_size, dist),
                              images, points_file="point_cloud.ply", undistort=undistort)
