"""Two-view reconstruction from matches: E, pose, triangulation, uncertainty and trust.

The pipeline (book chapter 4, done right):

1. essential matrix from calibrated points (5-point, USAC), then a local
   optimisation of the pose on its inliers (robust Sampson refinement),
   restarted until the best fit is found twice (:func:`scene3D.epipolar.fit_essential`),
2. model selection: a pure rotation (no baseline) is refused when a rotation
   homography explains the matches as well as the essential matrix
   (:func:`scene3D.degeneracy.motion_model_choice`); a planar scene is refused
   unless matches off the plane rule out the other pose a plane allows,
3. pose by cheirality over all inliers; ``F = K^-T E K^-1`` for epipolar lines,
4. triangulation, keeping points in front of both cameras with small
   reprojection error and enough parallax,
5. the pose's first-order covariance (:func:`scene3D.refinement.relative_pose_covariance`,
   parametrisation in :mod:`scene3D.uncertainty`) and each point's depth uncertainty,
6. trust (:func:`trust_warnings`): a pose is untrusted when its uncertainty is too
   large for the purpose (``TwoViewSettings.uncertainty_sigmas`` standard
   deviations beyond ``uncertainty_limit_deg``), or when something the covariance
   cannot see is at work: restarts that end at distinct optima, a focal length
   that does not fit the calibration (:func:`check_focal_length`), too few inliers
   for the covariance to be estimated or for wrong matches not to agree by chance.

Frames: points are in the camera-1 frame, ``x_cam2 = R x_cam1 + t``, ``|t| = 1``
(the scale is unknown).
"""

from __future__ import annotations

import logging
import time
from dataclasses import dataclass, field, fields

import numpy as np
from numpy.typing import ArrayLike

from .degeneracy import (
    MotionModelChoice,
    is_rotation_homography,
    lower_cost_plane_pose,
    motion_model_choice,
    off_plane_evidence,
    plane_poses,
)
from .epipolar import (
    EssentialFit,
    essential_distances,
    essential_from_pose,
    estimate_homography,
    fit_essential,
    fundamental_from_essential,
    inlier_threshold_px,
    loss_scale_px,
    noise_sigma_px,
)
from .errors import ReconstructionError
from .features import Matches
from .geometry import (
    FloatArray,
    as_matrix,
    as_points2d,
    check_same_length,
    median,
)
from .pose import choose_pose
from .refinement import (
    FocalFit,
    bundle_adjust_two_view,
    fit_focal_scale,
    relative_pose_covariance,
)
from .triangulation import parallax_angles_deg, reprojection_errors
from .uncertainty import PoseUncertainty, depth_sigmas, tangent_basis

__all__ = [  # the plane checks lived here before scene3D.degeneracy
    "TwoViewGeometry", "TwoViewReconstruction", "TwoViewSettings", "check_focal_length",
    "is_rotation_homography", "off_plane_evidence", "plane_poses", "reconstruct_from_matches",
    "reconstruct_two_view", "sample_colors", "trust_warnings",
]

logger = logging.getLogger(__name__)


@dataclass(frozen=True)
class TwoViewSettings:
    """Thresholds of the two-view pipeline (defaults suit the book's 768 px images).

    Attributes
    ----------
    threshold_px : float
        Robust-estimation inlier threshold for F, E and H, in pixels. The local
        optimisation of E raises it, at most twofold, when the matches are noisier
        than it assumes (:func:`scene3D.epipolar.inlier_threshold_px`).
    max_starts : int
        Most robust estimations of E (each locally optimised); the best is kept
        once two starts agree on it (:func:`scene3D.epipolar.fit_essential`).
        1 gives a single start, as plain OpenCV does.
    restart_agreement_deg : float
        When no pose was found twice, the result is still trusted if every start's
        optimum lies within this angle of the best (distinct optima, one pose to
        that accuracy); beyond it the result is marked untrusted: a covariance
        describes one optimum and cannot see the others.
    min_matches, min_inliers, min_points : int
        Below these counts the pair is refused.
    min_point_parallax_deg : float
        Points seen under a smaller angle are dropped (their depth is unreliable),
        unless that leaves fewer than ``min_points`` (a small baseline): then every
        point in front of both cameras is kept, with its depth uncertainty.
    max_reprojection_px : float
        Points reprojecting worse than this in either view are dropped.
    planar_ratio : float
        Homography inliers / essential inliers above which the pair is checked for
        the planar ambiguity (:func:`scene3D.degeneracy.off_plane_evidence`).
    min_off_plane_matches : int
        A (nearly) planar pair is refused unless at least this many matches off the
        plane rule out the other pose that the plane allows.
    uncertainty_limit_deg, uncertainty_sigmas : float, float
        The purpose: a pose is untrusted when ``uncertainty_sigmas`` standard
        deviations of its rotation or of its translation direction
        (``rotation_sigma_deg``, ``translation_sigma_deg`` of the result) exceed
        ``uncertainty_limit_deg``. The default, 3 sigma within 2 deg, keeps the
        direction within 2 deg with at least 98.9 % probability.
    max_rotation_share : float
        The pose is untrusted when a rotation alone explains more than this share of
        the inliers (within three noise standard deviations;
        :func:`scene3D.degeneracy.motion_model_choice`): most matches show no
        parallax, and the translation rests on the others, which a moving object
        would explain as well as a camera that moved (on OpenCV's ``left*.jpg``, a
        still camera and a chessboard moved by hand, 5 of 78 pairs came back
        trusted, with translation sigmas of 0.001-0.5 deg, without this check).
    trusted_inliers : int
        Fewer inliers leave the pose untrusted whatever its covariance says: a
        covariance estimated from few residuals is itself uncertain, and random
        matches can agree on a wrong pose by chance (a few dozen of them among a
        few hundred; ``tests/test_twoview.py``).
    trusted_inlier_ratio, trusted_parallax_deg, planar_warning_ratio : float
        Not verdicts: when the uncertainty is too large, the warning names the
        likely causes, an inlier share of the matches below ``trusted_inlier_ratio``
        (wide baseline, repeated texture), a median parallax below
        ``trusted_parallax_deg`` (short baseline), a homography explaining more
        than ``planar_warning_ratio`` of the inliers (a nearly planar scene).
    max_focal_mismatch, focal_mismatch_sigmas : float, float
        The result is marked untrusted when the matches call for a focal length more
        than ``1 + max_focal_mismatch`` times larger or smaller than the
        calibration's, by more than ``focal_mismatch_sigmas`` standard deviations
        (:func:`scene3D.refinement.fit_focal_scale`): the calibration is probably
        for another camera, lens or zoom, and the pose is off by degrees. Three
        standard deviations of the sandwich estimate (five of the optimistic IRLS
        estimate before it): with the true K no right pose of the three Strecha
        scenes is flagged for its focal length (gaps 1-5, 768 and 1536 px).
    bundle_adjust : bool
        Finish with a two-view bundle adjustment of pose and points
        (:func:`scene3D.refinement.bundle_adjust_two_view`) with the same Cauchy
        loss as the local optimisation. Off by default: on the fountain-P11
        benchmark pairs it moves the poses by hundredths of a degree at most, closer
        to the truth on some pairs and further on others (at 768 px AUC@5deg 98.2
        against 98.4 without), for about 70-160 ms a pair (768-1536 px).
    """

    threshold_px: float = 1.0
    max_starts: int = 8
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
    max_focal_mismatch: float = 0.15
    focal_mismatch_sigmas: float = 3.0
    bundle_adjust: bool = False


@dataclass(frozen=True)
class TwoViewGeometry:
    """Pose and structure of a pair, as found from its correspondences alone.

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
    homography_inlier_ratio : float
        Homography inliers / essential inliers (near 1: planar scene or no baseline).
    trusted : bool
        False when a check raised a doubt; see ``warnings``.
    warnings : tuple[str, ...]
        Human-readable doubts about the result.
    inlier_pts1, inlier_pts2 : (M, 2) float64
        All essential-matrix inliers (before triangulation filters).
    refinement_s : float
        Seconds spent refining the pose (and bundle adjusting, if asked).
    robust_starts : int
        Robust estimations of E run (:func:`scene3D.epipolar.fit_essential`); when
        the best pose was not found twice in ``TwoViewSettings.max_starts`` of them
        and their optima lie more than ``TwoViewSettings.restart_agreement_deg``
        apart, the result is untrusted.
    robust_spread_deg : float
        How far the other starts' optima lie from the chosen one
        (:attr:`scene3D.epipolar.EssentialFit.spread_deg`; 0 when they all agree).
    focal_scale, focal_scale_sigma : float
        The focal length the inliers call for, as a multiple of the calibration's,
        and its standard deviation (:func:`scene3D.refinement.fit_focal_scale`;
        near 1 when the calibration fits, the sigma infinite when the pair cannot
        tell).
    pose_covariance : (5, 5) float64
        First-order covariance of the pose (radians^2) in the parametrisation of
        :mod:`scene3D.uncertainty`: rows 0-2 the rotation vector ``w`` of
        ``R <- exp([w]x) R`` (camera-2 frame), rows 3-4 the step of ``t`` along the
        rows of ``tangent_basis(t)`` (:attr:`pose_uncertainty` has both). Infinite
        when the matches do not determine the pose.
    rotation_sigma_deg, translation_sigma_deg : float
        1-sigma angles of the rotation and of the translation direction along their
        worst axes (square roots of the largest eigenvalues of the covariance's
        rotation and direction blocks), in degrees.
    noise_sigma_px : float
        Robust standard deviation of the keypoint noise, per coordinate, measured on
        the inliers (:func:`scene3D.epipolar.noise_sigma_px`).
    depth_sigmas : (N,) float64
        1-sigma depth of each point in camera 1, in units of the baseline, from the
        pose covariance and the keypoint noise (:func:`scene3D.uncertainty.depth_sigmas`);
        divide by ``points3d[:, 2]`` for a relative uncertainty.
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
    homography_inlier_ratio: float
    trusted: bool
    warnings: tuple[str, ...]
    inlier_pts1: FloatArray
    inlier_pts2: FloatArray
    refinement_s: float = 0.0
    robust_starts: int = 1
    robust_spread_deg: float = 0.0
    focal_scale: float = 1.0
    focal_scale_sigma: float = float("inf")
    pose_covariance: FloatArray = field(default_factory=lambda: np.full((5, 5), np.inf))
    rotation_sigma_deg: float = float("inf")
    translation_sigma_deg: float = float("inf")
    noise_sigma_px: float = float("nan")
    depth_sigmas: FloatArray = field(default_factory=lambda: np.zeros(0))

    @property
    def pose_uncertainty(self) -> PoseUncertainty:
        """The covariance with the tangent basis of ``t`` it refers to."""
        return PoseUncertainty(self.pose_covariance, tangent_basis(self.t), self.noise_sigma_px)


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


def sample_colors(img_bgr: np.ndarray, points: FloatArray) -> np.ndarray:
    """RGB ``uint8`` colours ``(N, 3)`` of a BGR image at pixels ``(N, 2)`` (nearest pixel)."""
    h, w = img_bgr.shape[:2]
    x = np.clip(np.rint(points[:, 0]).astype(int), 0, w - 1)
    y = np.clip(np.rint(points[:, 1]).astype(int), 0, h - 1)
    if img_bgr.ndim == 2:
        grey = img_bgr[y, x]
        return np.stack([grey, grey, grey], axis=1).astype(np.uint8)
    return img_bgr[y, x, ::-1].astype(np.uint8)


def _deg(angle: float) -> str:
    """An angle in degrees to two significant digits: '2.4', '0.31', '0.037'."""
    return f"{angle:.1f}" if angle >= 1 else f"{angle:.2g}"


def _sigmas_text(uncertainty: PoseUncertainty) -> str:
    """'translation direction +-2.4 deg, rotation +-0.31 deg (1 sigma)'."""
    return (f"translation direction +-{_deg(uncertainty.translation_sigma_deg)} deg, rotation "
            f"+-{_deg(uncertainty.rotation_sigma_deg)} deg (1 sigma)")


def trust_warnings(uncertainty: PoseUncertainty, num_matches: int, num_inliers: int,
                   median_parallax_deg: float, homography_ratio: float, s: TwoViewSettings,
                   fit: EssentialFit | None = None, focal: FocalFit | None = None,
                   rotation_share: float = 0.0) -> list[str]:
    """Reasons to doubt a pose that passed every hard check (empty: trusted).

    The verdicts:

    - the uncertainty (``uncertainty``, :class:`scene3D.uncertainty.PoseUncertainty`)
      is too large for the purpose: ``s.uncertainty_sigmas`` standard deviations of
      the rotation or the translation direction exceed ``s.uncertainty_limit_deg``.
      The warning names the likely causes among few inliers, a small inlier share of
      the matches, weak parallax and a nearly planar scene (``s.trusted_inliers``,
      ``s.trusted_inlier_ratio``, ``s.trusted_parallax_deg``,
      ``s.planar_warning_ratio``), which are explanations, not verdicts of their own;
    - what a covariance cannot see: the robust restarts of ``fit`` never reached the
      best pose twice and their optima lie further apart than
      ``s.restart_agreement_deg`` (several optima); the focal length the matches call
      for (``focal``, :func:`scene3D.refinement.fit_focal_scale`) differs from the
      calibration's by more than ``s.max_focal_mismatch`` and
      ``s.focal_mismatch_sigmas`` standard deviations; fewer than
      ``s.trusted_inliers`` inliers, too few to estimate a covariance from and few
      enough for wrong matches to agree by chance; a rotation alone explains more than
      ``s.max_rotation_share`` of the inliers (``rotation_share``,
      :func:`scene3D.degeneracy.motion_model_choice`), so the translation rests on
      the few that show parallax.

    Every warning quotes the uncertainty.
    """
    sigmas = _sigmas_text(uncertainty)
    warnings = []
    limit = s.uncertainty_limit_deg / s.uncertainty_sigmas
    if max(uncertainty.rotation_sigma_deg, uncertainty.translation_sigma_deg) > limit:
        causes = []
        if num_inliers < s.trusted_inliers:
            causes.append(f"only {num_inliers} inliers")
        if num_inliers < s.trusted_inlier_ratio * num_matches:
            causes.append(f"only {num_inliers / num_matches:.0%} of the {num_matches} matches "
                          "are inliers (wide baseline or repeated texture)")
        if median_parallax_deg < s.trusted_parallax_deg:
            causes.append(f"weak parallax ({_deg(median_parallax_deg)} deg median)")
        if homography_ratio > s.planar_warning_ratio:
            causes.append(f"a homography explains {homography_ratio:.0%} of the inliers "
                          "(a nearly planar scene or a short baseline)")
        warnings.append(f"uncertain pose: {sigmas}, more than {s.uncertainty_limit_deg:g} deg "
                        f"at {s.uncertainty_sigmas:g} sigma"
                        + (f"; {', '.join(causes)}" if causes else ""))
    elif num_inliers < s.trusted_inliers:
        warnings.append(f"only {num_inliers} inliers: too few to rely on the pose's "
                        f"{sigmas}")
    if rotation_share > s.max_rotation_share:
        warnings.append(f"a rotation alone explains {rotation_share:.0%} of the inliers: the "
                        f"translation rests on the other {1 - rotation_share:.0%}, which a "
                        "moving object would explain as well as a camera that moved (the "
                        f"{sigmas} assume a rigid scene)")
    if (fit is not None and s.max_starts > 1 and not fit.confirmed
            and fit.spread_deg > s.restart_agreement_deg):
        warnings.append(f"no pose was found twice in {fit.starts} robust starts: poses "
                        f"up to {fit.spread_deg:.1f} deg apart fit the matches about "
                        f"equally well (the best one's {sigmas} cannot show this)")
    if focal is not None:
        log_scale = abs(np.log(focal.scale))
        if (log_scale > np.log1p(s.max_focal_mismatch)
                and log_scale > s.focal_mismatch_sigmas * focal.sigma_log):
            warnings.append(
                f"the matches fit a focal length {focal.scale:.2f} times the calibration's "
                f"(+-{focal.scale * focal.sigma_log:.2f}): is the calibration for this camera, "
                f"lens and zoom? The pose may be off by degrees, beyond its {sigmas}")
    return warnings


def check_focal_length(R: FloatArray, t: FloatArray, p1: FloatArray, p2: FloatArray,
                       inliers: np.ndarray, K: FloatArray, threshold_px: float,
                       scale_px: float, rounds: int = 3) -> FocalFit:
    """The focal length the matches call for (:func:`scene3D.refinement.fit_focal_scale`).

    ``p1, p2`` are all the correspondences ``(N, 2)``, ``inliers`` the ``(N,) bool``
    inliers of the pose ``R, t`` found with ``K``. Those inliers were chosen under
    ``K``: with a wrong focal length they favour the matches that fit it, so they
    are re-selected under the fitted focal length (at ``threshold_px``) and the fit
    repeated (as :func:`scene3D.epipolar.refine_essential` does for the pose), under
    a Cauchy loss of scale ``scale_px``.
    """
    focal = fit_focal_scale(R, t, p1[inliers], p2[inliers], K, "cauchy", scale_px)
    for _ in range(rounds - 1):
        K_s = K @ np.diag([focal.scale, focal.scale, 1.0])
        new = essential_distances(essential_from_pose(focal.R, focal.t), p1, p2, K_s) \
            <= threshold_px
        if new.sum() < 6 or np.array_equal(new, inliers):
            break
        inliers = new
        focal = fit_focal_scale(focal.R, focal.t, p1[inliers], p2[inliers], K, "cauchy",
                                scale_px, initial_scale=focal.scale)
    return focal


def _motion(E: FloatArray, in1: FloatArray, in2: FloatArray, K: FloatArray, H: FloatArray,
            threshold_px: float) -> MotionModelChoice:
    """:func:`scene3D.degeneracy.motion_model_choice` on the inliers of ``E``.

    The noise is floored at a thousandth of the threshold (as the loss scale is,
    :func:`scene3D.epipolar.loss_scale_px`): exact matches leave a homography fitted
    in float arithmetic with errors of 1e-6 px that would otherwise count as misfit.
    """
    distances = essential_distances(E, in1, in2, K)
    noise = max(noise_sigma_px(distances), 1e-3 * threshold_px)
    return motion_model_choice(in1, in2, K, distances, noise, H)


def reconstruct_from_matches(
    pts1: ArrayLike,
    pts2: ArrayLike,
    K: ArrayLike,
    settings: TwoViewSettings | None = None,
) -> TwoViewGeometry:
    """Estimate pose and structure from correspondences (the geometric core).

    Parameters
    ----------
    pts1, pts2 : (N, 2) array_like
        Matched pixels in image 1 and image 2.
    K : (3, 3) array_like
        Intrinsics shared by both images.

    Returns
    -------
    TwoViewGeometry

    Raises
    ------
    ReconstructionError
        Too few matches / inliers / points, a pure rotation (``"no_parallax"``), a
        planar scene, or no cheirality winner.
    """
    s = settings or TwoViewSettings()
    p1 = as_points2d(pts1, "pts1")
    p2 = as_points2d(pts2, "pts2")
    check_same_length(p1, p2)
    K = as_matrix(K, (3, 3), "K")
    n = len(p1)
    if n < s.min_matches:
        raise ReconstructionError(
            "too_few_matches", "too few matches between the images",
            matches=n, required=s.min_matches,
        )
    fit = fit_essential(p1, p2, K, s.threshold_px, max_starts=s.max_starts)
    E, inliers, refine_s = fit.E, fit.inliers, fit.refinement_s
    logger.debug("essential matrix: %d robust starts", fit.starts)
    num_inliers = int(inliers.sum())
    if not np.all(np.isfinite(E)) or num_inliers < s.min_inliers:
        raise ReconstructionError(
            "too_few_inliers", "too few matches agree on an essential matrix",
            matches=n, inliers=num_inliers, required=s.min_inliers,
        )
    in1, in2 = p1[inliers], p2[inliers]
    H, h_inliers = estimate_homography(in1, in2, s.threshold_px)
    h_ratio = float(h_inliers.sum()) / num_inliers
    motion = _motion(E, in1, in2, K, H, s.threshold_px)
    if motion.pure_rotation:
        raise ReconstructionError(
            "no_parallax",
            "the images are related by a pure rotation (no baseline): a rotation explains "
            "the matches as well as an essential matrix, and depth cannot be recovered",
            inliers=num_inliers, rotation_gric=motion.rotation_gric,
            essential_gric=motion.essential_gric,
        )
    if h_ratio > s.planar_ratio:
        better = lower_cost_plane_pose(E, inliers, h_inliers, H, p1, p2, K, s.threshold_px)
        if better is not None:
            E, inliers = better
            num_inliers = int(inliers.sum())
            in1, in2 = p1[inliers], p2[inliers]
            H, h_inliers = estimate_homography(in1, in2, s.threshold_px)
            h_ratio = float(h_inliers.sum()) / num_inliers
            motion = _motion(E, in1, in2, K, H, s.threshold_px)
    # A plane allows two poses, unless the depth off it is measurable (the essential
    # matrix explains the matches better than the homography: a short baseline).
    planar = h_ratio > s.planar_ratio and motion.planar
    R, t, points, front = choose_pose(E, in1, in2, K)
    if planar:
        evidence = off_plane_evidence(H, K, R, t, in1, in2, h_inliers, s.threshold_px)
        if evidence < s.min_off_plane_matches:
            raise ReconstructionError(
                "planar_scene",
                "one homography explains the matches (a planar scene): the relative pose is "
                "ambiguous; add depth to the view", inliers=num_inliers,
                homography_inlier_ratio=h_ratio, off_plane_evidence=evidence,
                required=s.min_off_plane_matches,
            )
    parallax = np.where(front, parallax_angles_deg(np.nan_to_num(points), R, t), 0.0)
    errors = np.full((len(in1), 2), np.inf)
    errors[front] = reprojection_errors(points[front], in1[front], in2[front], K, R, t)
    valid = front & (errors.max(axis=1) <= s.max_reprojection_px)
    keep = valid & (parallax >= s.min_point_parallax_deg)
    if keep.sum() < s.min_points:
        # A small baseline: every point is weakly triangulated; keep them all, each with
        # its depth uncertainty, rather than refuse a pose that the model selection found.
        keep = valid
    if keep.sum() < s.min_points:
        raise ReconstructionError(
            "too_few_points", "too few points triangulate reliably",
            inliers=num_inliers, in_front=int(front.sum()), kept=int(keep.sum()),
            required=s.min_points,
        )
    median_kept_parallax = median(parallax[keep])
    t_focal = time.perf_counter()
    # The noise of these inliers sets the losses of the focal check and the adjustment,
    # as it does the local optimisation's (scene3D.epipolar.refine_essential).
    distances = essential_distances(E, in1, in2, K)
    loss_scale = loss_scale_px(distances, s.threshold_px)
    focal = check_focal_length(R, t, p1, p2, inliers, K,
                               inlier_threshold_px(distances, s.threshold_px), loss_scale)
    refine_s += time.perf_counter() - t_focal
    points, pts1_kept, pts2_kept = points[keep], in1[keep], in2[keep]
    kept_errors = errors[keep]
    if s.bundle_adjust:
        t_ba = time.perf_counter()
        R, t, points = bundle_adjust_two_view(R, t, points, pts1_kept, pts2_kept, K,
                                              loss="cauchy", scale_px=loss_scale)
        E = essential_from_pose(R, t)
        E = E / np.linalg.norm(E)
        kept_errors = reprojection_errors(points, pts1_kept, pts2_kept, K, R, t)
        refine_s += time.perf_counter() - t_ba
    # The covariance at the final pose: the Sampson cost is the bundle adjustment's with
    # the points eliminated, to first order, so it serves after an adjustment too.
    uncertainty = PoseUncertainty(
        relative_pose_covariance(R, t, in1, in2, K, "cauchy", loss_scale), tangent_basis(t),
        noise_sigma_px(distances))
    point_sigmas = depth_sigmas(points, K, R, t, uncertainty.covariance,
                                uncertainty.noise_sigma_px)
    warnings = trust_warnings(uncertainty, n, num_inliers, median_kept_parallax, h_ratio, s,
                              fit, focal, motion.rotation_share)
    F = fundamental_from_essential(E, K)  # the epipolar geometry the final pose obeys
    return TwoViewGeometry(
        R=R, t=t, points3d=points, pts1=pts1_kept, pts2=pts2_kept, K=K, F=F, E=E,
        num_matches=n, num_inliers=num_inliers,
        reprojection_rmse_px=float(np.sqrt(np.mean(kept_errors**2))),
        median_parallax_deg=median_kept_parallax,
        homography_inlier_ratio=h_ratio, trusted=not warnings, warnings=tuple(warnings),
        inlier_pts1=in1, inlier_pts2=in2, refinement_s=refine_s, robust_starts=fit.starts,
        robust_spread_deg=fit.spread_deg, focal_scale=focal.scale,
        focal_scale_sigma=focal.scale * focal.sigma_log,
        pose_covariance=uncertainty.covariance,
        rotation_sigma_deg=uncertainty.rotation_sigma_deg,
        translation_sigma_deg=uncertainty.translation_sigma_deg,
        noise_sigma_px=uncertainty.noise_sigma_px, depth_sigmas=point_sigmas,
    )


def reconstruct_two_view(
    img1: np.ndarray,
    matches: Matches,
    K: ArrayLike,
    settings: TwoViewSettings | None = None,
) -> TwoViewReconstruction:
    """Reconstruct a pair from its matches; ``img1`` (BGR) gives the point colours.

    See :func:`reconstruct_from_matches` for the steps and the errors raised.
    """
    t0 = time.perf_counter()
    geometry = reconstruct_from_matches(matches.pts1, matches.pts2, K, settings)
    t1 = time.perf_counter()
    refinement_s = geometry.refinement_s
    colors = sample_colors(img1, geometry.pts1)
    timings = dict(matches.timings_s)
    timings["geometry"] = t1 - t0 - refinement_s
    timings["refinement"] = refinement_s
    timings["total"] = sum(timings.values())
    for w in geometry.warnings:
        logger.warning("%s", w)
    return TwoViewReconstruction(colors=colors, feature=matches.feature, timings_s=timings,
                                 **{f.name: getattr(geometry, f.name)
                                    for f in fields(TwoViewGeometry)})
