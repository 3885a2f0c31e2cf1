"""Whether to trust a two-view pose: the verdicts that follow from its uncertainty and
what the uncertainty cannot see (see :mod:`scene3D.twoview`)."""

from __future__ import annotations

from collections.abc import Callable
from typing import NamedTuple, TypeVar

import numpy as np

from ..geometry.camera import principal_point_hint
from ..geometry.conventions import FloatArray, pose_angle_deg
from ..geometry.pose import nearest_decomposition
from ..optim.uncertainty import CHI2_99_POSE, PoseUncertainty, pose_difference_chi2
from .distortion_fit import DistortionFit, fit_radial_distortion
from .essential_fit import EssentialFit
from .flow_check import FLOW_BAND_PX, FlowCheck
from .focal_fit import FocalFit, fit_focal_scale
from .results import TwoViewSettings

#: The fits that :func:`_reselected_fit` repeats.
FitT = TypeVar("FitT", FocalFit, DistortionFit)


class _KWords(NamedTuple):
    """How the warnings name where ``K`` came from."""

    whose: str  # "a focal length 1.05 times {whose}"
    question: str  # after a focal length the matches refute
    zoom: str  # "a camera that only turned, {zoom}?"
    leaves_out: str  # "a distortion ... that {leaves_out}"
    distortion_question: str  # "{...}, and are the photos as the camera took them?"


#: Where ``K`` can come from (``K_source`` of :func:`scene3D.twoview.reconstruct_from_matches`),
#: as the warnings name it: a calibration (the default; also a ``K`` given in Python),
#: the camera files of a dataset's ground truth (``scene3d evaluate``), or the focal length
#: that other photos of the collection gave (a further model of ``reconstruct-views``
#: without a calibration).
K_SOURCES: dict[str, _KWords] = {
    "calibration": _KWords(
        "the calibration's", "is the calibration for this camera, lens and zoom?",
        "with a calibration for another zoom", "the calibration leaves out",
        "Is the calibration for this camera and lens, with its distortion (calibrate.py "
        "fits it)"),
    "camera files": _KWords(
        "the camera files'", "are the camera files for these photos and this zoom?",
        "with camera files for another zoom", "the camera files leave out",
        "Are the camera files for this camera and lens, with its distortion"),
    "other photos": _KWords(
        "the one the other photos gave", "are these photos from the same camera and zoom "
        "as the others?", "at another zoom than the other photos",
        "the camera found from the other photos leaves out",
        "Are these photos from the same camera and lens as the others"),
}


def k_words(K_source: str) -> _KWords:
    """The words for ``K_source`` (a key of :data:`K_SOURCES`); ``ValueError`` naming the
    argument for another.

    Parameters
    ----------
    K_source : str
        A key of :data:`K_SOURCES`.

    Returns
    -------
    _KWords

    Raises
    ------
    ValueError
        For another ``K_source``.
    """
    if K_source not in K_SOURCES:
        raise ValueError(f"`K_source` must be one of {', '.join(map(repr, K_SOURCES))}, "
                         f"got {K_source!r}")
    return K_SOURCES[K_source]


def _deg(angle: float) -> str:
    """An angle in degrees to two significant digits: '2.4', '0.31', '0.037'."""
    return f"{angle:.1f}" if angle >= 1 else f"{angle:.2g}"


def sigmas_text(rotation_sigma_deg: float, translation_sigma_deg: float) -> str:
    """'translation direction +-2.4 deg, rotation +-0.31 deg (1 sigma)': how warnings quote
    a pose's uncertainty.

    Parameters
    ----------
    rotation_sigma_deg, translation_sigma_deg : float
        1-sigma uncertainties (deg).

    Returns
    -------
    str
    """
    return (f"translation direction +-{_deg(translation_sigma_deg)} deg, rotation "
            f"+-{_deg(rotation_sigma_deg)} deg (1 sigma)")


def beyond_uncertainty_limit(rotation_sigma_deg: float, translation_sigma_deg: float,
                             s: TwoViewSettings) -> bool:
    """``s.uncertainty_sigmas`` standard deviations of the rotation or the translation
    direction exceed ``s.uncertainty_limit_deg``: too uncertain for the purpose.

    Parameters
    ----------
    rotation_sigma_deg, translation_sigma_deg : float
        1-sigma uncertainties (deg).
    s : TwoViewSettings
        The limits.

    Returns
    -------
    bool
    """
    limit = s.uncertainty_limit_deg / s.uncertainty_sigmas
    return max(rotation_sigma_deg, translation_sigma_deg) > limit


def rival_chi2(fit: EssentialFit, R: FloatArray, t: FloatArray, covariance: FloatArray) -> float:
    """How far the restarts' rival optima lie from the pose ``R, t`` under its covariance.

    The largest :func:`scene3D.optim.uncertainty.pose_difference_chi2` (5 degrees of freedom)
    over ``fit.rivals`` (:attr:`scene3D.twoview.essential_fit.EssentialFit.rivals`, each taken in
    its decomposition nearest to ``R, t``); 0 when there are none. Within
    :data:`scene3D.optim.uncertainty.CHI2_99_POSE` a rival is one the ``(5, 5)``
    ``covariance`` allows for: the sigmas already say the pose is known no better.

    Parameters
    ----------
    fit : EssentialFit
        The robust fit, with its ``rivals``.
    R, t : (3, 3), (3,) array_like
        Relative pose ``x_cam2 = R x_cam1 + t`` (``|t| = 1``: the scale is unknown).
    covariance : (5, 5) array_like
        The pose's covariance.

    Returns
    -------
    float
    """
    worst = 0.0
    for E in fit.rivals:
        R_other, t_other = nearest_decomposition(E, R, t)
        worst = max(worst, pose_difference_chi2(R, t, R_other, t_other, covariance))
    return worst


def trust_warnings(uncertainty: PoseUncertainty, num_matches: int, num_inliers: int,
                   median_parallax_deg: float, homography_ratio: float, s: TwoViewSettings,
                   fit: EssentialFit | None = None, focal: FocalFit | None = None,
                   rotation_share: float = 0.0, rivals_chi2: float = float("inf"),
                   rotation_focal_scale: float = 1.0,
                   focal_ratio: FocalFit | None = None,
                   behind_share: float = 0.0, K_source: str = "calibration") -> list[str]:
    """Reasons to doubt a pose that passed every hard check (empty: trusted).

    ``K_source`` (:data:`K_SOURCES`) says where ``K`` came from, for the warnings' words:
    "the calibration's" focal length, "the camera files'", or "the one the other photos
    gave".

    The verdicts:

    - the uncertainty (``uncertainty``, :class:`scene3D.optim.uncertainty.PoseUncertainty`)
      is too large for the purpose: ``s.uncertainty_sigmas`` standard deviations of
      the rotation or the translation direction exceed ``s.uncertainty_limit_deg``.
      The warning names the likely causes among few inliers, a small inlier share of
      the matches, weak parallax and a nearly planar scene (``s.trusted_inliers``,
      ``s.trusted_inlier_ratio``, ``s.trusted_parallax_deg``,
      ``s.planar_warning_ratio``), which are explanations, not verdicts of their own;
    - what a covariance cannot see: the robust restarts of ``fit`` never reached the
      best pose twice, their optima lie further apart than
      ``s.restart_agreement_deg``, and one of them lies outside the region the
      covariance allows (``rivals_chi2``, :func:`rival_chi2`, above
      :data:`scene3D.optim.uncertainty.CHI2_99_POSE`; by default every rival counts): several
      optima; or, found twice, the best has a rival outside that region further away
      than ``s.uncertainty_limit_deg``: the pose may be off by more than the purpose
      allows; the focal length the matches call
      for (``focal``, :func:`scene3D.twoview.focal_fit.fit_focal_scale`) differs from the
      calibration's by more than ``s.max_focal_mismatch`` and
      ``s.focal_mismatch_sigmas`` standard deviations, or image 2's against image 1's
      (``focal_ratio``, :func:`scene3D.twoview.focal_fit.fit_focal_ratio`) by as much; fewer than
      ``s.trusted_inliers`` inliers, too few to estimate a covariance from and few
      enough for wrong matches to agree by chance; a rotation alone explains more than
      ``s.max_rotation_share`` of the inliers (``rotation_share``,
      :func:`scene3D.twoview.degeneracy.motion_model_choice`; under a focal length
      ``rotation_focal_scale`` times the calibration's when that rotation fitted better),
      so the translation rests on the few that show parallax; the inlier threshold cuts
      off more than ``s.max_noise_cut_share`` of the matches that fit the pose
      (``uncertainty.noise_cut_share``): noisier matches than it can hold; more than
      ``s.max_behind_share`` of the inliers triangulate behind a camera beyond the
      noise (``behind_share``): wrong matches near their epipolar lines, so many that
      the pose itself may rest on wrong matches that agree.

    Every warning quotes the uncertainty.

    Parameters
    ----------
    uncertainty : PoseUncertainty
        The pose's uncertainty.
    num_matches, num_inliers : int
        Matches and inliers of the pair.
    median_parallax_deg : float
        Median triangulation angle (deg).
    homography_ratio : float
        Share of the inliers a homography explains.
    s : TwoViewSettings
        The limits.
    fit : EssentialFit or None, default None
        The robust fit and its restarts.
    focal : FocalFit or None, default None
        Focal length the matches call for.
    rotation_share : float, default 0.0
        Share of inliers a pure rotation explains.
    rivals_chi2 : float, default inf
        :func:`rival_chi2`.
    rotation_focal_scale : float, default 1.0
        Focal factor of the rotation that fitted.
    focal_ratio : FocalFit or None, default None
        Image 2's focal length against image 1's.
    behind_share : float, default 0.0
        Share of inliers behind a camera beyond the noise.
    K_source : str, default "calibration"
        Where ``K`` came from.

    Returns
    -------
    list of str
    """
    words = k_words(K_source)
    sigmas = sigmas_text(uncertainty.rotation_sigma_deg, uncertainty.translation_sigma_deg)
    warnings = []
    if beyond_uncertainty_limit(uncertainty.rotation_sigma_deg,
                                uncertainty.translation_sigma_deg, s):
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
    if uncertainty.noise_cut_share > s.max_noise_cut_share:
        warnings.append(f"the matches are noisy (+-{uncertainty.noise_sigma_px:.2g} px) for the "
                        f"inlier threshold: it cuts off about "
                        f"{uncertainty.noise_cut_share:.0%} of the matches that fit the pose, "
                        "which then rests on those that happen to fit best; its "
                        f"{sigmas} understate how far off it may be (a larger "
                        "TwoViewSettings.threshold_px would hold them)")
    if behind_share > s.max_behind_share:
        warnings.append(f"{behind_share:.0%} of the inliers triangulate behind a camera: wrong "
                        "matches that happen to fit the pose's epipolar lines, or an object "
                        "that moved between the photos; with that many, the pose itself may "
                        "rest on wrong matches that agree (repeated texture?), which its "
                        f"{sigmas} cannot show")
    if rotation_share > s.max_rotation_share:
        under = ("" if rotation_focal_scale == 1.0 else
                 f" (under a focal length {rotation_focal_scale:.2f} times {words.whose}: "
                 f"a camera that only turned, {words.zoom}?)")
        warnings.append(f"a rotation alone explains {rotation_share:.0%} of the inliers{under}: "
                        f"the translation rests on the other {1 - rotation_share:.0%}, which a "
                        "moving object would explain as well as a camera that moved (the "
                        f"{sigmas} assume a rigid scene)")
    if fit is not None and s.max_starts > 1 and rivals_chi2 > CHI2_99_POSE:
        if not fit.confirmed and fit.spread_deg > s.restart_agreement_deg:
            warnings.append(f"no pose was found twice in {fit.starts} robust starts: poses "
                            f"up to {fit.spread_deg:.1f} deg apart fit the matches about "
                            f"equally well (the best one's {sigmas} cannot show this)")
        elif fit.confirmed and fit.spread_deg > s.uncertainty_limit_deg:
            warnings.append(f"another pose {fit.spread_deg:.1f} deg away fits the matches "
                            "about as well (the robust starts reached both): the pose may "
                            f"be off by that much, which its {sigmas} cannot show")
    if focal is not None and focal_mismatch(focal.scale, focal.sigma_log, s):
        warnings.append(
            f"the matches fit a focal length {focal.scale:.2f} times {words.whose} "
            f"(+-{focal.scale * focal.sigma_log:.2f}): {words.question} The pose may be off "
            f"by degrees, beyond its {sigmas}")
    if focal_ratio is not None and focal_mismatch(focal_ratio.scale, focal_ratio.sigma_log,
                                                       s):
        warnings.append(
            f"the matches fit image 2 with a focal length {focal_ratio.scale:.2f} times image "
            f"1's (+-{focal_ratio.scale * focal_ratio.sigma_log:.2g}): were the photos taken "
            "at two zoom settings, or one cropped or resized? One calibration holds for "
            f"both only at one zoom; the pose may be off by degrees, beyond its {sigmas}")
    return warnings


def focal_mismatch(scale: float, sigma_log: float, s: TwoViewSettings) -> bool:
    """A focal length ``scale`` times the calibration's, ``sigma_log`` the standard deviation
    of its log (:class:`scene3D.twoview.focal_fit.FocalFit`), that refutes the calibration: beyond
    ``1 + s.max_focal_mismatch`` either way, by more than ``s.focal_mismatch_sigmas``
    standard deviations.

    Parameters
    ----------
    scale : float
        Focal length over the calibration's.
    sigma_log : float
        Standard deviation of ``log(scale)``.
    s : TwoViewSettings
        The limits.

    Returns
    -------
    bool
    """
    log_scale = abs(np.log(scale))
    return (log_scale > np.log1p(s.max_focal_mismatch)
            and log_scale > s.focal_mismatch_sigmas * sigma_log)


def focal_agreement(scale: float, sigma_log: float, s: TwoViewSettings) -> bool:
    """A focal length ``scale`` times the calibration's that confirms it: within
    ``1 + s.max_focal_mismatch`` either way, and known well enough to tell
    (``s.focal_mismatch_sigmas`` standard deviations of its log, ``sigma_log``, inside that
    band). A pair whose matches leave the focal length wide open neither confirms nor
    refutes (:func:`focal_mismatch`) the calibration.

    Parameters
    ----------
    scale : float
        Focal length over the calibration's.
    sigma_log : float
        Standard deviation of ``log(scale)``.
    s : TwoViewSettings
        The limits.

    Returns
    -------
    bool
    """
    band = np.log1p(s.max_focal_mismatch)
    return bool(abs(np.log(scale)) <= band and s.focal_mismatch_sigmas * sigma_log < band)


def principal_point_warning(K: FloatArray, pts1: FloatArray, pts2: FloatArray,
                            image_size: tuple[int, int] | None = None) -> str | None:
    """Why ``K``'s principal point may not be these images', or None.

    With their ``image_size`` (width, height): :func:`scene3D.geometry.camera.principal_point_hint`
    (more than 20 % of a side from the centre: a ``K`` for larger photos, for turned
    ones, or another camera's). Without it, judged from the matches alone: a real
    camera's principal point lies near the image centre, inside the spread of the
    matched pixels ``pts1, pts2`` ``(N, 2)`` or near it. When it lies beyond their
    extent by more than half that extent on both axes, every match sits in one quadrant
    of it, far off: the mark of a ``K`` for larger photos (a ``K`` for 3072 px photos
    with matches of a 768 px copy gives a trusted pose 40 deg off). A crop of a corner
    keeps the principal point within half its extent of it.

    Parameters
    ----------
    K : (3, 3) array_like
        Intrinsics.
    pts1, pts2 : (N, 2) array_like
        Matched pixels (OpenCV convention) in images 1 and 2.
    image_size : (int, int) or None, default None
        ``(width, height)`` in px.

    Returns
    -------
    str or None
    """
    if image_size is not None:
        return principal_point_hint(K, image_size) or None
    points = np.vstack([pts1, pts2])
    low, high = points.min(axis=0), points.max(axis=0)
    centre = K[:2, 2]
    beyond = np.maximum(low - centre, centre - high)  # > 0 outside, per axis
    if not np.all(beyond > 0.5 * (high - low)):
        return None
    return (f"the principal point ({centre[0]:.0f}, {centre[1]:.0f}) of K lies far outside "
            f"the matches (x {low[0]:.0f}-{high[0]:.0f}, y {low[1]:.0f}-{high[1]:.0f} px): is K "
            "for images of another size? (give image_size to check it)")


def check_focal_length(R: FloatArray, t: FloatArray, p1: FloatArray, p2: FloatArray,
                       inliers: np.ndarray, K: FloatArray, threshold_px: float,
                       scale_px: float, rounds: int = 3,
                       fit: Callable[..., FocalFit] = fit_focal_scale) -> FocalFit:
    """The focal length the matches call for (:func:`scene3D.twoview.focal_fit.fit_focal_scale`,
    or with ``fit=fit_focal_ratio`` image 2's against image 1's).

    ``p1, p2`` are all the correspondences ``(N, 2)``, ``inliers`` the ``(N,) bool``
    inliers of the pose ``R, t`` found with ``K``. Those inliers were chosen under
    ``K``: with a wrong focal length they favour the matches that fit it, so they
    are re-selected under the fitted focal lengths (at ``threshold_px``) and the fit
    repeated (as :func:`scene3D.twoview.essential_fit.refine_essential` does for the pose), under
    a Cauchy loss of scale ``scale_px``.

    Parameters
    ----------
    R, t : (3, 3), (3,) array_like
        Relative pose ``x_cam2 = R x_cam1 + t`` (``|t| = 1``: the scale is unknown).
    p1, p2 : (N, 2) array_like
        All the correspondences (pixels, OpenCV convention).
    inliers : (N,) bool ndarray
        Inliers of the pose.
    K : (3, 3) array_like
        The calibration's intrinsics.
    threshold_px : float
        Inlier threshold on the Sampson distance (px).
    scale_px : float
        Scale of the Cauchy loss (px).
    rounds : int, default 3
        Re-selection rounds.
    fit : callable, default fit_focal_scale
        :func:`scene3D.twoview.focal_fit.fit_focal_scale` or ``fit_focal_ratio``.

    Returns
    -------
    FocalFit
    """
    return _reselected_fit(fit, R, t, p1, p2, inliers, K, threshold_px, scale_px, rounds)


def check_distortion(R: FloatArray, t: FloatArray, p1: FloatArray, p2: FloatArray,
                     inliers: np.ndarray, K: FloatArray, threshold_px: float,
                     scale_px: float, rounds: int = 3) -> DistortionFit:
    """The radial lens distortion the matches call for, and the pose with it
    (:func:`scene3D.twoview.distortion_fit.fit_radial_distortion`), the inliers re-selected
    under it as :func:`check_focal_length` does.

    Parameters
    ----------
    R, t : (3, 3), (3,) array_like
        Relative pose ``x_cam2 = R x_cam1 + t`` (``|t| = 1``: the scale is unknown).
    p1, p2 : (N, 2) array_like
        All the correspondences (pixels, OpenCV convention).
    inliers : (N,) bool ndarray
        Inliers of the pose.
    K : (3, 3) array_like
        The calibration's intrinsics.
    threshold_px : float
        Inlier threshold on the Sampson distance (px).
    scale_px : float
        Scale of the Cauchy loss (px).
    rounds : int, default 3
        Re-selection rounds.

    Returns
    -------
    DistortionFit
    """
    return _reselected_fit(fit_radial_distortion, R, t, p1, p2, inliers, K, threshold_px,
                           scale_px, rounds)


def _reselected_fit(fit: Callable[..., FitT], R: FloatArray, t: FloatArray, p1: FloatArray,
                    p2: FloatArray, inliers: np.ndarray, K: FloatArray, threshold_px: float,
                    scale_px: float, rounds: int) -> FitT:
    """``fit`` (pose and one more unknown) on the inliers, re-selected among all matches
    ``p1, p2`` within ``threshold_px`` of each fit and refitted, ``rounds`` times at most."""
    result = fit(R, t, p1[inliers], p2[inliers], K, "cauchy", scale_px)
    for _ in range(rounds - 1):
        new = np.abs(result.residuals(K, p1, p2)) <= threshold_px
        if new.sum() < 6 or np.array_equal(new, inliers):
            break
        inliers = new
        result = fit(result.R, result.t, p1[inliers], p2[inliers], K, "cauchy", scale_px, 30,
                     result.parameter)
    return result


#: A fitted distortion counts only beyond this many of its standard deviations.
DISTORTION_SIGMAS = 3.0


def distortion_warning(R: FloatArray, t: FloatArray, fit: DistortionFit, K: FloatArray,
                       far_pixel: FloatArray, where: str, s: TwoViewSettings,
                       uncertainty: PoseUncertainty | None = None,
                       K_source: str = "calibration") -> str | None:
    """Why a lens distortion that the calibration ``K`` leaves out may have put the pose
    ``R, t`` off, or None.

    ``fit`` is the pose refined with one radial distortion (:func:`check_distortion`).
    The pose is doubted when the matches call for a distortion (more than
    :data:`DISTORTION_SIGMAS` standard deviations from none) and the pose with it lies
    more than twice ``s.uncertainty_limit_deg`` away: which of the two is right, the
    matches cannot say, and they lie further apart than the purpose allows. Right
    poses mostly move less, wrong ones through an uncorrected lens mostly more
    (docs/benchmarks.md#the-distortion-check).
    ``far_pixel`` ``(2,)`` is where the distortion's shift is quoted, as ``where`` (the
    image corner farthest from the principal point: "the image's corners"); the pose's
    ``uncertainty``, when given, is quoted too; ``K_source`` (:data:`K_SOURCES`) names
    where ``K`` came from.

    Parameters
    ----------
    R, t : (3, 3), (3,) array_like
        Relative pose ``x_cam2 = R x_cam1 + t`` (``|t| = 1``: the scale is unknown).
    fit : DistortionFit
        The pose refined with one radial distortion.
    K : (3, 3) array_like
        The calibration's intrinsics.
    far_pixel : (2,) array_like
        Pixel where the distortion's shift is quoted.
    where : str
        Words for ``far_pixel``.
    s : TwoViewSettings
        The limits.
    uncertainty : PoseUncertainty or None, default None
        Quoted when given.
    K_source : str, default "calibration"
        Where ``K`` came from.

    Returns
    -------
    str or None
    """
    words = k_words(K_source)
    apart = pose_angle_deg(fit.R, fit.t, R, t)
    if apart <= 2 * s.uncertainty_limit_deg or not abs(fit.k) > DISTORTION_SIGMAS * fit.sigma:
        return None
    kind = "barrel" if fit.k < 0 else "pincushion"
    beyond = ("" if uncertainty is None else ", beyond its " + sigmas_text(
        uncertainty.rotation_sigma_deg, uncertainty.translation_sigma_deg))
    return (f"the matches fit a pose {_deg(apart)} deg from this one with a {kind} lens "
            f"distortion that moves {where} by {fit.shift_px(K, far_pixel):.0f} px "
            f"and that {words.leaves_out}: the pose may be off by degrees{beyond}. "
            f"{words.distortion_question}, and are the photos as the camera took them? "
            "(Wrong matches that agree, on repeated texture, can do the same.)")


#: Why the flow may doubt a pose that every sparse check passed.
_REPEATED_TEXTURE = ("sparse matches on repeated texture, such as rows of identical windows, "
                     "can agree on a wrong pose")


def flow_warning(R: FloatArray, t: FloatArray, flow: FlowCheck | None,
                 s: TwoViewSettings) -> str | None:
    """Why the dense optical flow doubts the pose ``R, t``, or None.

    ``flow`` is :func:`scene3D.twoview.flow_check.check_pose_against_flow`'s verdict (None: too
    little texture to judge); the pose is doubted when the flow's own pose explains more
    than ``s.max_flow_gain`` of the flow more and lies at least half
    ``s.uncertainty_limit_deg`` away (a pose nearer the flow's than that is near enough
    for the purpose, whatever the flow prefers), or, whatever the gain, when the flow's
    pose lies more than twice ``s.uncertainty_limit_deg`` away: refined from this pose,
    the flow left its basin (a second photo that shows only a strip of the first's
    scene, say: docs/benchmarks.md#the-dense-flow-check).

    Parameters
    ----------
    R, t : (3, 3), (3,) array_like
        Relative pose ``x_cam2 = R x_cam1 + t`` (``|t| = 1``: the scale is unknown).
    flow : FlowCheck or None
        The flow's verdict.
    s : TwoViewSettings
        The limits.

    Returns
    -------
    str or None
    """
    if flow is None or s.max_flow_gain >= 1.0:
        return None
    apart = pose_angle_deg(flow.R, flow.t, R, t)
    shares = (f"it puts {flow.flow_share:.0%} of the flow of {flow.points} textured pixels "
              f"within {FLOW_BAND_PX:g} px of its epipolar lines, this pose {flow.share:.0%}")
    if apart > 2 * s.uncertainty_limit_deg:
        return (f"the pose refined on the dense optical flow between the images lies "
                f"{_deg(apart)} deg from this one ({shares}; {_REPEATED_TEXTURE})")
    if flow.gain <= s.max_flow_gain or apart < s.uncertainty_limit_deg / 2:
        return None
    return (f"the dense optical flow between the images fits a pose {_deg(apart)} deg away "
            f"better: {shares} ({_REPEATED_TEXTURE})")

