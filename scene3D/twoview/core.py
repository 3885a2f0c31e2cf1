"""The two-view reconstruction from matches (the pipeline of :mod:`scene3D.twoview`)."""

from __future__ import annotations

import logging
import time
from dataclasses import fields, replace

import numpy as np
from numpy.typing import ArrayLike

from ..errors import ReconstructionError, log_result_warnings
from ..features.matching import Matches, check_image, to_gray
from ..geometry.camera import check_intrinsics_for_native_size, validate_intrinsics
from ..geometry.conventions import (
    FloatArray,
    as_points2d,
    check_same_length,
    distinct_correspondences,
    median,
    pose_angle_deg,
)
from ..geometry.epipolar import (
    essential_distances,
    essential_from_pose,
    estimate_homography,
    fundamental_from_essential,
)
from ..geometry.pose import choose_pose
from ..geometry.triangulation import (
    behind_at_scene_parallax,
    behind_beyond_noise,
    parallax_angles_deg,
    reprojection_errors,
)
from ..io.images import bgr_order
from ..optim.bundle_two_view import bundle_adjust_two_view
from ..optim.refinement import refine_relative_pose, relative_pose_covariance
from ..optim.uncertainty import (
    PoseUncertainty,
    depth_sigmas,
    pose_error_coordinates,
    tangent_basis,
    truncated_noise,
)
from .degeneracy import (
    MotionModelChoice,
    lower_cost_plane_pose,
    motion_model_choice,
    off_plane_evidence,
    warped_copy_residual,
)
from .essential_fit import fit_essential, inlier_threshold_px, loss_scale_px, noise_sigma_px
from .flow_check import check_pose_against_images
from .focal_fit import fit_focal_ratio
from .measurements import TwoViewChecks, TwoViewFocal, TwoViewUncertainty
from .results import TwoViewGeometry, TwoViewReconstruction, TwoViewSettings
from .trust import (
    check_distortion,
    check_focal_length,
    distortion_warning,
    flow_warning,
    k_words,
    principal_point_warning,
    rival_chi2,
    trust_warnings,
)

logger = logging.getLogger(__name__)


def sample_colors(img_bgr: np.ndarray, points: FloatArray) -> np.ndarray:
    """RGB ``uint8`` colours ``(N, 3)`` of a BGR ``(H, W, 3)`` image at pixels ``(N, 2)``
    (nearest pixel); a grey ``(H, W)`` image gives its value in all three channels.

    Parameters
    ----------
    img_bgr : (H, W, 3) or (H, W) uint8 ndarray
        BGR or grey image.
    points : (N, 2) array_like
        Pixels (OpenCV convention), clipped to the image.

    Returns
    -------
    (N, 3) uint8 ndarray
        RGB colours.
    """
    h, w = img_bgr.shape[:2]
    x = np.clip(np.rint(points[:, 0]).astype(int), 0, w - 1)
    y = np.clip(np.rint(points[:, 1]).astype(int), 0, h - 1)
    if img_bgr.ndim == 2:
        grey = img_bgr[y, x]
        return np.stack([grey, grey, grey], axis=1).astype(np.uint8)
    return img_bgr[y, x, ::-1].astype(np.uint8)


def _motion(E: FloatArray, in1: FloatArray, in2: FloatArray, K: FloatArray, H: FloatArray,
            threshold_px: float, free_focal: bool) -> MotionModelChoice:
    """:func:`scene3D.twoview.degeneracy.motion_model_choice` on the inliers of ``E``.

    The noise is floored at a thousandth of the threshold (as the loss scale is,
    :func:`scene3D.twoview.essential_fit.loss_scale_px`): exact matches leave a homography fitted
    in float arithmetic with errors of 1e-6 px that would otherwise count as misfit.
    """
    distances = essential_distances(E, in1, in2, K)
    noise = max(noise_sigma_px(distances), 1e-3 * threshold_px)
    return motion_model_choice(in1, in2, K, distances, noise, H, free_focal)


def pose_covariance(R: FloatArray, t: FloatArray, in1: FloatArray, in2: FloatArray,
                    K: FloatArray, behind: np.ndarray, loss_scale_px: float,
                    variance_factor: float = 1.0) -> FloatArray:
    """Covariance ``(5, 5)`` of the pose, with the pull of the inliers behind the cameras
    and the noise that the inlier threshold cut off.

    The sandwich covariance of the robust Sampson fit over the inliers ``in1, in2``
    ``(N, 2)`` (:func:`scene3D.optim.refinement.relative_pose_covariance`; parametrisation of
    :mod:`scene3D.optim.uncertainty`) describes the noise of correct matches. A wrong match
    that passes the inlier threshold is no such noise: anywhere along its epipolar line,
    its rays meet at a large angle and it pulls the translation direction by more than
    its term in the sandwich says. Those that lie behind a camera beyond the noise
    (``behind`` ``(N,) bool``, :func:`scene3D.geometry.triangulation.behind_beyond_noise`) are
    known to be wrong, yet they are not dropped from the pose: one that lies on its
    epipolar line still constrains it (a repeated structure along the line, a
    duplicate), and without them the real benchmark's poses are no better
    (docs/benchmarks.md#the-uncertainty-against-exact-ground-truth, "tried and not
    kept"). Their pull
    is measured instead: the pose refined without them differs by ``delta`` (5,), and
    the covariance is that of the error's second moment, bias included,
    ``C + delta delta^T`` (the mean squared error is the variance plus the bias
    squared). With no such inlier it is ``C``.

    The sandwich measures the noise by the inliers' residuals, which the inlier
    threshold cut: their variance is ``variance_factor`` times the noise's
    (:attr:`scene3D.optim.uncertainty.TruncatedNoise.variance_factor`), so ``C`` is divided
    by it (1 and no change when the threshold lies far out in the noise's tail;
    infinite when the noise is unknown, 0).

    ``R, t`` ``x_cam2 = R x_cam1 + t`` (``|t| = 1``) is the refined pose and
    ``loss_scale_px`` the scale of its Cauchy loss.

    Parameters
    ----------
    R, t : (3, 3), (3,) array_like
        Relative pose ``x_cam2 = R x_cam1 + t`` (``|t| = 1``: the scale is unknown).
    in1, in2 : (N, 2) array_like
        Inlier pixels in images 1 and 2.
    K : (3, 3) array_like
        Intrinsics shared by both views.
    behind : (N,) bool ndarray
        Inliers that triangulate behind a camera beyond the noise.
    loss_scale_px : float
        Scale of the Cauchy loss (px).
    variance_factor : float, default 1.0
        Variance of the cut inlier residuals over the noise's; <= 0 gives an infinite
        covariance.

    Returns
    -------
    (5, 5) float64 ndarray
        In the parametrisation of :mod:`scene3D.optim.uncertainty` (rotation 3, translation
        direction 2).
    """
    if variance_factor <= 0:
        return np.full((5, 5), np.inf)
    covariance = relative_pose_covariance(R, t, in1, in2, K, "cauchy",
                                          loss_scale_px) / variance_factor
    if not behind.any() or (~behind).sum() < 6 or not np.all(np.isfinite(covariance)):
        return covariance
    R_without, t_without = refine_relative_pose(R, t, in1[~behind], in2[~behind], K, "cauchy",
                                                loss_scale_px)
    delta = np.concatenate(pose_error_coordinates(R, t, R_without, t_without))
    return covariance + np.outer(delta, delta)


def reconstruct_from_matches(
    pts1: ArrayLike,
    pts2: ArrayLike,
    K: ArrayLike,
    settings: TwoViewSettings | None = None,
    image_size: tuple[int, int] | None = None,
    *,
    K_source: str = "calibration",
) -> TwoViewGeometry:
    """Estimate pose and structure from correspondences (the geometric core).

    Parameters
    ----------
    pts1, pts2 : (N, 2) array_like
        Matched pixels in image 1 and image 2. A correspondence listed more than once
        (:func:`scene3D.geometry.distinct_correspondences`; SIFT lists one twice when
        both orientations of a keypoint match) weighs as listed in the robust fit of E
        and counts once in everything after it: the match and inlier counts, the
        checks, the points and the pose's uncertainty.
    K : (3, 3) array_like
        Intrinsics shared by both images, for images of the size the points were found
        in.
    settings : TwoViewSettings, optional
    image_size : (width, height), optional
        The images' size: ``K`` is then checked against it
        (:func:`scene3D.geometry.camera.check_intrinsics_for_native_size`), and a principal
        point far from its centre marks the pose untrusted; without it, one far outside
        the matches does (:func:`scene3D.twoview.trust.principal_point_warning`).
    K_source : str, optional
        Where ``K`` came from, for the warnings' words
        (:data:`scene3D.twoview.trust.K_SOURCES`): ``"calibration"`` (the default: "a
        focal length 1.05 times the calibration's"), ``"camera files"`` (ground-truth
        cameras, as ``scene3d evaluate`` gives: "... times the camera files'") or
        ``"other photos"`` (the focal length other photos gave, as for a further model of
        ``reconstruct-views`` without a calibration).

    Returns
    -------
    TwoViewGeometry

    Raises
    ------
    ValueError
        Bad points, a ``K`` that cannot be for images of ``image_size``, or a
        ``K_source`` not in ``K_SOURCES``.
    ReconstructionError
        Too few matches / inliers / points, a pure rotation (``"no_parallax"``), a
        planar scene, or no cheirality winner.
    """
    s = TwoViewSettings() if settings is None else settings
    if not isinstance(s, TwoViewSettings):
        raise TypeError(f"`settings` must be a scene3D.TwoViewSettings "
                        f"(TwoViewSettings(**values) makes one from a dict), got "
                        f"{type(s).__name__}")
    p1 = as_points2d(pts1, "pts1")
    p2 = as_points2d(pts2, "pts2")
    check_same_length(p1, p2)
    K = validate_intrinsics(K)
    if image_size is not None:
        check_intrinsics_for_native_size(K, image_size)
    k_words(K_source)  # a ValueError now, not after the work
    distinct = distinct_correspondences(p1, p2)
    n = len(distinct)
    if n < s.min_matches:
        raise ReconstructionError(
            "too_few_matches", "too few matches between the images",
            matches=n, required=s.min_matches,
        )
    fit = fit_essential(p1, p2, K, s.threshold_px, max_starts=s.max_starts,
                        shift_test_min_inliers=s.trusted_inliers)
    # From here on each correspondence once: a copy is no second observation of its
    # noise, nor a second vote for a model.
    p1, p2 = p1[distinct], p2[distinct]
    E, inliers, refine_s = fit.E, fit.inliers[distinct], fit.refinement_s
    fitted_px = fit.fitted_threshold_px  # the threshold the pose's inliers were refined at
    logger.debug("essential matrix: %d robust starts", fit.starts)
    num_inliers = int(inliers.sum())
    if not np.all(np.isfinite(E)) or num_inliers < s.min_inliers:
        raise ReconstructionError(
            "too_few_inliers", "too few matches agree on an essential matrix: do the photos "
            "show the same, still scene (not two places, nor mostly moving things)?",
            matches=n, inliers=num_inliers, required=s.min_inliers,
        )
    in1, in2 = p1[inliers], p2[inliers]
    H, h_inliers = estimate_homography(in1, in2, s.threshold_px)
    h_ratio = float(h_inliers.sum()) / num_inliers
    motion = _motion(E, in1, in2, K, H, s.threshold_px, h_ratio > s.planar_ratio)
    if motion.pure_rotation:
        # Matches that do not move at all: most likely one photo given twice.
        still = median(np.linalg.norm(in2 - in1, axis=1)) <= s.threshold_px
        raise ReconstructionError(
            "no_parallax",
            "the images are related by a pure rotation (no baseline): a rotation explains "
            "the matches as well as an essential matrix, and depth cannot be recovered"
            + ("; the matches do not even move between the images (one photo twice?)"
               if still else ""),
            inliers=num_inliers, rotation_gric=motion.rotation_gric,
            essential_gric=motion.essential_gric,
        )
    if h_ratio > s.planar_ratio:
        better = lower_cost_plane_pose(E, inliers, h_inliers, H, p1, p2, K, s.threshold_px)
        if better is not None:
            E, inliers = better
            fitted_px = s.threshold_px
            num_inliers = int(inliers.sum())
            in1, in2 = p1[inliers], p2[inliers]
            H, h_inliers = estimate_homography(in1, in2, s.threshold_px)
            h_ratio = float(h_inliers.sum()) / num_inliers
            motion = _motion(E, in1, in2, K, H, s.threshold_px, h_ratio > s.planar_ratio)
    # A plane allows two poses, unless the depth off it is measurable (the essential
    # matrix explains the matches better than the homography: a short baseline).
    planar = h_ratio > s.planar_ratio and motion.planar
    try:
        R, t, points, front = choose_pose(E, in1, in2, K)
    except ReconstructionError as exc:
        # Points at infinity lie in front of no camera and behind none: a camera that only
        # turned, which the model selection could not tell from a short baseline, ends here.
        share, scale = motion.widest_rotation
        if share <= s.max_rotation_share:
            raise
        under = "" if scale == 1.0 else f" under a focal length {scale:.2f} times K's"
        raise ReconstructionError(
            exc.reason, f"{exc.message}; a rotation alone{under} explains {share:.0%} of the "
            "inliers (did the camera only turn?)", **exc.counts) from None
    # The noise of these inliers sets the losses of the focal check and the adjustment,
    # as it does the local optimisation's (scene3D.twoview.essential_fit.refine_essential).
    distances = essential_distances(E, in1, in2, K)
    noise = noise_sigma_px(distances)
    behind = behind_beyond_noise(points, R, t, K, noise)
    # Inliers behind at the scene's parallax: wrong matches, not far ones a slightly wrong
    # K pushed across infinity (scene3D.geometry.triangulation.behind_at_scene_parallax).
    angles = parallax_angles_deg(np.nan_to_num(points), R, t)
    behind_share = float(behind_at_scene_parallax(angles, behind, front).sum()) / num_inliers
    if planar:
        evidence = off_plane_evidence(H, K, R, t, in1, in2, h_inliers, s.threshold_px)
        if evidence < s.min_off_plane_matches:
            turned = (f"; or a camera that only turned, with a calibration for another zoom "
                      f"(a rotation under a focal length {motion.focal_scale:.2f} times K's "
                      f"explains {motion.focal_rotation_share:.0%} of them)"
                      if motion.focal_rotation_share > s.max_rotation_share else "")
            raise ReconstructionError(
                "planar_scene",
                "one homography explains the matches (a planar scene): the relative pose is "
                "ambiguous; add depth to the view" + turned, inliers=num_inliers,
                homography_inlier_ratio=h_ratio, off_plane_evidence=evidence,
                required=s.min_off_plane_matches,
            )
    copy_px = (warped_copy_residual(H, in1, in2, h_inliers, distances)
               if h_ratio > s.planar_ratio else None)
    if copy_px is not None:
        raise ReconstructionError(
            "planar_scene",
            f"one homography explains {h_ratio:.0%} of the matches, and they fit to "
            f"{copy_px:.1g} px, better than a camera locates its keypoints: one image is a "
            "warped copy of the other (shifted, scaled, turned), not a second view of the "
            "scene, or the matches are noise-free ones of a planar scene; no pose follows "
            "from either", inliers=num_inliers, homography_inlier_ratio=h_ratio)
    parallax = np.where(front, angles, 0.0)
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
    loss_scale = loss_scale_px(distances, fitted_px)
    inlier_threshold = inlier_threshold_px(distances, fitted_px)
    # The focal check re-selects its inliers at the given threshold even when the pose was
    # fitted within the noise: a wrong focal length leaves matches off by more than the
    # noise, which a tighter selection would drop and so hide
    # (docs/benchmarks.md#the-focal-length-check).
    check_px = inlier_threshold_px(distances, s.threshold_px)
    focal = check_focal_length(R, t, p1, p2, inliers, K, check_px, loss_scale)
    focal_ratio = check_focal_length(R, t, p1, p2, inliers, K, check_px, loss_scale,
                                     fit=fit_focal_ratio)
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
    # The inliers were re-selected at the threshold their noise calls for: how much of
    # that noise it cut (scene3D.twoview.essential_fit.refine_essential).
    cut = truncated_noise(distances, inlier_threshold)
    uncertainty = PoseUncertainty(pose_covariance(R, t, in1, in2, K, behind, loss_scale,
                                                  cut.variance_factor),
                                  tangent_basis(t), noise, cut.cut_share)
    point_sigmas = depth_sigmas(points, K, R, t, uncertainty.covariance,
                                uncertainty.noise_sigma_px)
    # A rotation under another focal length counts where it explains more of the matches.
    rotation_share, rotation_focal_scale = motion.widest_rotation
    warnings = trust_warnings(uncertainty, n, num_inliers, median_kept_parallax, h_ratio, s,
                              fit, focal, rotation_share,
                              rival_chi2(fit, R, t, uncertainty.covariance),
                              rotation_focal_scale, focal_ratio, behind_share, K_source)
    # A K for larger photos or turned ones gave trusted poses 11-40 deg off.
    if (misplaced := principal_point_warning(K, p1, p2, image_size)) is not None:
        warnings.append(misplaced)
    distortion = None
    if not warnings and s.check_distortion:  # a doubt is already said; this costs a refit
        t_distortion = time.perf_counter()
        distortion = check_distortion(R, t, p1, p2, inliers, K, check_px, loss_scale)
        refine_s += time.perf_counter() - t_distortion
        far, where = _farthest_pixel(K, image_size, np.vstack([p1, p2]))
        if (doubt := distortion_warning(R, t, distortion, K, far, where, s, uncertainty,
                                        K_source)):
            warnings.append(doubt)
    F = fundamental_from_essential(E, K)  # the epipolar geometry the final pose obeys
    return TwoViewGeometry(
        R=R, t=t, points3d=points, pts1=pts1_kept, pts2=pts2_kept, K=K, F=F, E=E,
        num_matches=n, num_inliers=num_inliers,
        reprojection_rmse_px=float(np.sqrt(np.mean(kept_errors**2))),
        median_parallax_deg=median_kept_parallax, trusted=not warnings,
        warnings=tuple(warnings), inlier_pts1=in1, inlier_pts2=in2, refinement_s=refine_s,
        focal=TwoViewFocal.from_fits(focal, focal_ratio),
        uncertainty=TwoViewUncertainty.from_pose(uncertainty, point_sigmas),
        checks=TwoViewChecks(
            homography_inlier_ratio=h_ratio, robust_starts=fit.starts,
            robust_spread_deg=fit.spread_deg, behind_share=behind_share,
            distortion_k=np.nan if distortion is None else distortion.k,
            distortion_pose_shift_deg=(np.nan if distortion is None else
                                       pose_angle_deg(distortion.R, distortion.t, R, t))),
    )


def _farthest_pixel(K: FloatArray, image_size: tuple[int, int] | None,
                    points: FloatArray) -> tuple[FloatArray, str]:
    """``(2,)`` the image corner farthest from ``K``'s principal point, or without the
    ``image_size`` (width, height) the farthest of the matched ``points`` ``(N, 2)``, and
    what it is, for a message."""
    where = "the farthest match"
    if image_size is not None:
        w, h = image_size
        points = np.array([[0.0, 0.0], [w - 1.0, 0.0], [0.0, h - 1.0], [w - 1.0, h - 1.0]])
        where = "the image's corners"
    return points[np.argmax(np.sum((points - K[:2, 2]) ** 2, axis=1))], where


def check_against_flow(geometry: TwoViewGeometry, img1: np.ndarray, img2: np.ndarray,
                       settings: TwoViewSettings | None = None) -> TwoViewGeometry:
    """A pose found from sparse matches, checked against the dense optical flow between
    the images (:mod:`scene3D.twoview.flow_check`).

    ``img1, img2`` are the working images ``(H, W, 3)`` BGR or ``(H, W)`` grey ``uint8``
    that ``geometry``'s points were found in. Only a trusted pose is checked (a doubt
    is already said), and none when ``settings.max_flow_gain`` is 1. The result then
    carries ``flow_gain`` and, when the flow doubts the pose
    (:func:`scene3D.twoview.trust.flow_warning`), a warning and ``trusted=False``. The
    flow never lifts a doubt: refined from the pose, under the same ``K``, it stays
    near a pose that a wrong focal length, a zoom or a moving object put wrong. About
    0.05 s: the flow is taken at 768 px at most (docs/benchmarks.md#the-dense-flow-check).

    Parameters
    ----------
    geometry : TwoViewGeometry
        The pose found from sparse matches.
    img1, img2 : (H, W, 3) or (H, W) uint8 ndarray
        The working images, one size.
    settings : TwoViewSettings or None, default None
        None for the defaults.

    Returns
    -------
    TwoViewGeometry
        ``geometry``, or a copy with ``flow_gain`` and any warning.


    Raises
    ------
    TypeError, ValueError
        If an image is not such an array, or the two differ in size.
    """
    s = TwoViewSettings() if settings is None else settings
    img1, img2 = check_image(img1, "img1"), check_image(img2, "img2")
    if img1.shape[:2] != img2.shape[:2]:
        raise ValueError(f"img1 and img2 must be of one size (one camera), got "
                         f"{img1.shape[1]}x{img1.shape[0]} and {img2.shape[1]}x{img2.shape[0]}")
    if not geometry.trusted or s.max_flow_gain >= 1.0:
        return geometry
    R, t = geometry.R, geometry.t
    flow = check_pose_against_images(R, t, geometry.K, to_gray(img1), to_gray(img2),
                                     geometry.inlier_pts1, geometry.inlier_pts2)
    if flow is None:
        return geometry
    doubt = flow_warning(R, t, flow, s)
    warnings = geometry.warnings + ((doubt,) if doubt else ())
    return replace(geometry, checks=replace(geometry.checks, flow_gain=flow.gain),
                   trusted=not warnings, warnings=warnings)


def require_enough_matches(matches: Matches, settings: TwoViewSettings | None = None) -> None:
    """Refuse a pair with fewer distinct matches than ``settings.min_matches``, saying why.

    :func:`reconstruct_from_matches` refuses it too; this also says whether an image
    had too few keypoints for that many matches (a blank, blurred or tiny photo) or
    the images had keypoints that did not match (not the same scene, or too far apart).

    Parameters
    ----------
    matches : Matches
        The pair's matches and keypoint counts.
    settings : TwoViewSettings or None, default None
        Gives ``min_matches``; None for the defaults.


    Raises
    ------
    ReconstructionError
        ``"too_few_matches"``, with ``matches``, ``required``, ``keypoints1`` and
        ``keypoints2``.
    """
    required = (settings or TwoViewSettings()).min_matches
    n = len(distinct_correspondences(matches.pts1, matches.pts2))
    if n >= required:
        return
    counts = dict(zip(("keypoints1", "keypoints2"), matches.num_keypoints))
    sparse = [f"image {i} has " + ("no keypoints" if k == 0 else
                                   f"only {k} keypoint" + ("s" if k > 1 else ""))
              for i, k in enumerate(matches.num_keypoints, 1) if k < required]
    why = (" and ".join(sparse) + " (a blank, blurred or very small photo?)" if sparse else
           "do the photos show the same scene, from viewpoints close enough to match?")
    raise ReconstructionError("too_few_matches", f"too few matches between the images: {why}",
                              matches=n, required=required, **counts)


def reconstruct_two_view(
    img1: np.ndarray,
    matches: Matches,
    K: ArrayLike,
    settings: TwoViewSettings | None = None,
    img2: np.ndarray | None = None,
    *,
    rgb: bool = False,
) -> TwoViewReconstruction:
    """Reconstruct a pair from its matches; ``img1`` gives the point colours.

    With ``img2``, a pose that passes every other check is also checked against the
    dense optical flow between the images (:func:`check_against_flow`): sparse matches
    on repeated texture can agree on a wrong pose that no statistic of their own shows.

    Parameters
    ----------
    img1 : (H, W, 3) or (H, W) uint8
        Image 1, the image ``matches.pts1`` were found in: BGR as cv2 loads it, whose
        colours come back as RGB, or grey, whose value is repeated in all three
        channels (grey points).
    matches : Matches
        Correspondences between image 1 and image 2
        (:func:`scene3D.features.find_matches`).
    K : (3, 3) array_like
        Intrinsics shared by both images.
    settings : TwoViewSettings, optional
    img2 : (H, W, 3) or (H, W) uint8, optional
        Image 2, the image ``matches.pts2`` were found in, of ``img1``'s size.
    rgb : bool, default False
        The images are RGB (PIL, imageio) rather than BGR as cv2 loads them
        (:func:`scene3D.io.images.bgr_order`); the colours come back RGB either way.

    Returns
    -------
    TwoViewReconstruction
        The pose ``x_cam2 = R @ x_cam1 + t`` (``|t| = 1``, scale unknown), the points
        in the camera-1 frame and their ``(N, 3)`` RGB ``uint8`` colours.

    Raises
    ------
    TypeError, ValueError
        If ``img1`` or ``img2`` is not such an image (a path, None, a float array;
        :func:`scene3D.features.check_image`) or ``img2`` not of ``img1``'s size,
        ``matches`` is not a :class:`Matches`, or ``K`` is not a camera matrix.
    ReconstructionError
        See :func:`reconstruct_from_matches` for the steps and the reasons
        (:func:`require_enough_matches` for too few matches).
    """
    img1 = check_image(bgr_order(img1, rgb), "img1")
    img2 = None if img2 is None else bgr_order(img2, rgb)
    if not isinstance(matches, Matches):
        raise TypeError(f"`matches` must be a scene3D.features.Matches (find_matches gives "
                        f"one), got {type(matches).__name__}")
    require_enough_matches(matches, settings)
    t0 = time.perf_counter()
    geometry = reconstruct_from_matches(matches.pts1, matches.pts2, K, settings,
                                        image_size=img1.shape[1::-1])
    t1 = time.perf_counter()
    if img2 is not None:
        geometry = check_against_flow(geometry, img1, img2, settings)
    t2 = time.perf_counter()
    refinement_s = geometry.refinement_s
    colors = sample_colors(img1, geometry.pts1)
    timings = dict(matches.timings_s)
    timings["geometry"] = t1 - t0 - refinement_s
    timings["refinement"] = refinement_s
    if img2 is not None:
        timings["flow check"] = t2 - t1
    timings["total"] = sum(timings.values())
    log_result_warnings(logger, geometry.warnings)
    return TwoViewReconstruction(colors=colors, feature=matches.feature, timings_s=timings,
                                 **{f.name: getattr(geometry, f.name)
                                    for f in fields(TwoViewGeometry)})
