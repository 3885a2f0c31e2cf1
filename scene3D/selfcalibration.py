"""Self-calibration of one focal length from the matches of a pair of photos.

Photos without a calibration file start from a focal length (EXIF, or a prior: see
:mod:`scene3D.intrinsics_prior`) with the principal point at the image centre. Two
views with rotation and depth determine a common focal length (H&Z section 19.5;
Bougnoux 1998): the pose and the focal length are refined together
(:func:`scene3D.refinement.fit_focal_scale`, through the two-view pipeline's focal
check :func:`scene3D.twoview.check_focal_length`).

What has to be iterated, and why a plain iteration is not enough:

- The essential-matrix inliers depend on ``K``: under a focal length 30 % off, the
  robust estimation keeps the matches that fit the wrong camera, and the focal fit
  on those inliers only moves part of the way. So the whole two-view estimate
  (:func:`scene3D.twoview.reconstruct_from_matches`: robust E, inliers, focal fit
  with inliers re-selected) is re-run under the refined ``K`` until the focal length
  it calls for stops changing (:func:`converge_focal`).
- That iteration is local. On scenes dominated by one plane (a facade: a plane
  fits any focal length; only the matches off it constrain it) it can settle
  where it started: from the 1.2 x prior, 8 of the 18 consecutive castle-P19
  pairs at 1536 px stayed 5-35 % off, 7 of them with sigmas below 1 %. So the starting
  point is chosen globally first (:func:`focal_profile`): the robust estimation is
  run at focal lengths spread over the prior's range, and each fit is scored over
  all matches by a robust cost whose scale follows the measured keypoint noise
  (three robust standard deviations, as the pipeline's inlier re-selection does;
  a 1 px threshold is five to ten noise sigmas at 1536 px, loose enough that
  wrong poses fitting a plane plus stray matches win). The iteration then starts
  from the best basins of that profile, and the one whose converged fit has the
  lowest cost is kept (:func:`self_calibrate_pair`).

How sure (:func:`focal_uncertainty`): the focal fit's first-order standard
deviation covers the noise of the matches given the model and the inliers, and is
far too small on its own (on the consecutive Strecha pairs at 1536 px the errors
were a median 1.7 to 8.8 times it, up to 58 times). Two
shares are added. The principal point is a guess (the centre); a real camera's
lies up to about 1 % of the image away (fountain-P11's: 0.5 % and 0.8 %), which
moves the fitted focal length by up to several percent on some pairs: the fit is
repeated with it moved by :attr:`SelfCalibrationSettings.principal_point_sigma`.
And a delete-a-cell jackknife over the inliers in image 1 measures how much the
estimate rests on one part of the scene.

Two things the local sigma cannot see. The pose's own covariance is conditional on
``K``: under a focal length 20 % off it still says hundredths of a degree. So the
pose covariance reported is marginal over the intrinsics
(:func:`marginal_pose_covariance`): how the pose moves with ``log f`` and the
principal point (:func:`scene3D.refinement.pose_intrinsics_sensitivity`) times their
covariance (:func:`intrinsics_covariance`) is added, and the two-view trust rule
(``TwoViewSettings.uncertainty_sigmas`` within ``uncertainty_limit_deg``) is applied
to it. And a pair can fit two focal lengths about equally well, each with its own
pose (repeated windows on a facade): a fit of the profile, or another basin, whose
cost over all matches is not significantly higher, judged with a standard error
measured over cells of the image (:func:`blocked_difference_z`), is a rival
(:func:`focal_rivals`): the focal length's sigma is widened to reach the farthest
rival, and a rival whose pose differs by more than the trust limit makes the result
untrusted.

The result is combined with the prior (inverse-variance, in ``log f``): with the
default prior the photos decide; with EXIF both count, unless they contradict each
other by more than three sigmas (an EXIF value can be plain wrong: a crop, a resized
copy, digital zoom): then photos that know the focal length to 10 % overrule it, and
the result is untrusted. When the photos know the focal length less well than the
prior (little rotation, optical axes that meet in one point: a large sigma), the
prior's value is kept and the result says so. A
focal length known to worse than
:attr:`SelfCalibrationSettings.max_trusted_sigma_log` (10 %), as when it rests on
the default prior, leaves the result untrusted; so does another basin that fits
about as well.

Frames as in :mod:`scene3D.geometry`; focal lengths are in pixels of the images the
matches come from (the working images).
"""

from __future__ import annotations

import logging
import math
import time
from dataclasses import dataclass, field, replace
from typing import NamedTuple

import numpy as np
from numpy.typing import ArrayLike

from .epipolar import (
    essential_cost,
    essential_costs,
    essential_distances,
    fit_essential,
    loss_scale_px,
    noise_sigma_px,
)
from .errors import ReconstructionError
from .geometry import (
    FloatArray,
    angle_between_deg,
    as_matrix,
    as_points2d,
    check_same_length,
    rotation_error_deg,
)
from .pose import choose_pose
from .refinement import fit_focal_scale, pose_intrinsics_sensitivity
from .twoview import TwoViewGeometry, TwoViewSettings, reconstruct_from_matches
from .uncertainty import depth_sigmas, largest_sigma_deg, marginal_covariance

logger = logging.getLogger(__name__)

#: ``calibration_source`` values: where the focal length of the final ``K`` comes from.
CALIBRATION_SOURCES = ("file", "exif", "exif+refined", "prior", "prior+refined")


@dataclass(frozen=True)
class SelfCalibrationSettings:
    """Choices of the focal self-calibration (the two-view thresholds are in
    :class:`scene3D.twoview.TwoViewSettings`).

    Attributes
    ----------
    search_sigmas : float
        The profile spans the prior's focal length times ``exp(+-search_sigmas *
        sigma_log)``, and at least ``min_search_factor`` either way.
    min_search_factor : float
        At least this factor either way (2: an EXIF focal length can be wrong by a
        crop or a digital zoom).
    search_step : float
        Ratio between neighbouring focal lengths of the profile.
    max_candidates : int
        Basins of the profile (lowest first) from which the iteration is run.
    max_iterations, tolerance_log : int, float
        The iteration stops when the focal length changes by less than
        ``tolerance_log`` (in ``log f``), or after ``max_iterations``.
    min_noise_threshold : float
        The profile's cost threshold (three noise sigmas) is not set below this
        fraction of ``TwoViewSettings.threshold_px`` (noise-free matches).
    principal_point_sigma : float
        Assumed standard deviation of the true principal point from the image
        centre, as a fraction of the longer side.
    jackknife_cells : int
        The inliers are split into ``jackknife_cells``^2 cells of image 1 for the
        jackknife (:func:`focal_uncertainty`).
    max_trusted_sigma_log : float
        A result whose focal length is known to worse than this (standard deviation
        of ``log f``) is untrusted: the pose may be off by degrees.
    ambiguity_cost : float
        Another basin whose converged cost is within this of the best one's (in
        the units of :func:`scene3D.epipolar.essential_cost`, where an outlier costs
        2.3) and whose focal length differs by more than three standard deviations
        makes the result ambiguous (untrusted).
    pose_principal_point : bool
        The pose's covariance includes the principal point's uncertainty
        (``principal_point_sigma``) besides the focal length's
        (:func:`marginal_pose_covariance`). It dominates the translation direction's
        sigma: a principal point 1 % of the longer side off turns the camera frame by
        about 0.6 deg whatever the resolution. False: the focal length's alone.
    rival_z : float
        A fit at a focal length more than three sigmas away whose cost over all
        matches is not higher by ``rival_z`` standard errors (blocked by the
        jackknife's cells, :func:`blocked_difference_z`; about a 2.5 % one-sided
        test) is a rival (:func:`focal_rivals`): the focal length's sigma is widened
        to reach it, and when its pose differs by more than
        ``TwoViewSettings.uncertainty_limit_deg`` the result is untrusted.
    """

    search_sigmas: float = 2.0
    min_search_factor: float = 2.0
    search_step: float = 1.15
    max_candidates: int = 3
    max_iterations: int = 8
    tolerance_log: float = 1e-3
    min_noise_threshold: float = 0.1
    principal_point_sigma: float = 0.01
    jackknife_cells: int = 3
    max_trusted_sigma_log: float = 0.1
    ambiguity_cost: float = 10.0
    pose_principal_point: bool = True
    rival_z: float = 2.0


@dataclass(frozen=True)
class FocalProfile:
    """The robust cost of the best pose at each of several focal lengths.

    Attributes
    ----------
    focal_px : (n,) float64
        The focal lengths tried, increasing.
    cost : (n,) float64
        :func:`scene3D.epipolar.essential_cost` of each one's robust fit over all
        matches, at ``threshold_px`` (inf where no fit was found).
    threshold_px : float
        The cost's threshold: three robust standard deviations of the keypoint
        noise (``noise_px``), within the limits of :class:`SelfCalibrationSettings`.
    noise_px : float
        The smallest robust noise sigma of the fits' inliers.
    essentials : (n, 3, 3) float64
        Each focal length's essential matrix (NaN where no fit was found).
    """

    focal_px: FloatArray
    cost: FloatArray
    threshold_px: float
    noise_px: float
    essentials: FloatArray = field(default_factory=lambda: np.zeros((0, 3, 3)))

    def basins(self) -> list[int]:
        """Indices of the profile's local minima, lowest cost first."""
        c, n = self.cost, len(self.cost)
        minima = [i for i in range(n) if np.isfinite(c[i])
                  and (i == 0 or c[i] <= c[i - 1]) and (i == n - 1 or c[i] <= c[i + 1])]
        return sorted(minima, key=lambda i: c[i])


class FocalUncertainty(NamedTuple):
    """Standard deviations of the fitted ``log f`` (:func:`focal_uncertainty`).

    Attributes
    ----------
    fit : float
        First order, from the fit's curvature and the residuals' spread: the noise
        of the matches, given the model and the inliers.
    jackknife : float
        Delete-a-cell jackknife over the inliers' cells in image 1: how much the
        estimate depends on one part of the scene (a plane, repeated texture, a
        cluster of wrong matches) beyond what the noise explains.
    principal_point : float
        How much it moves with the principal point one standard deviation away from
        the centre, in x and in y (root of the sum of squares).
    principal_point_shifts : tuple[float, float]
        The signed moves of ``log f`` with the principal point one standard
        deviation along x, and along y (their root sum of squares is
        ``principal_point``): how the focal length's error goes with the principal
        point's (:func:`intrinsics_covariance`).
    """

    fit: float
    jackknife: float
    principal_point: float
    principal_point_shifts: tuple[float, float] = (0.0, 0.0)

    @property
    def total(self) -> float:
        """``sqrt(max(fit, jackknife)^2 + principal_point^2)`` (the jackknife includes the
        noise the fit's sigma describes, so the larger of the two counts)."""
        return math.hypot(max(self.fit, self.jackknife), self.principal_point)


@dataclass(frozen=True)
class SelfCalibration:
    """The focal length found for a pair, and the pair's geometry under it.

    Attributes
    ----------
    K : (3, 3) float64
        The intrinsics used in the end (working images): ``geometry`` was
        estimated with them.
    focal_px : float
        ``K[0, 0]`` (= ``K[1, 1]``).
    focal_sigma_px : float
        Its standard deviation: the fit's and the principal point's share combined
        with the prior's, or the prior's alone when the photos did not determine it;
        at least the distance (in ``log f``) to the farthest focal length the matches
        do not tell apart from it (:func:`focal_rivals`).
    source : str
        ``"exif+refined"`` / ``"prior+refined"`` (the photos determined it), or
        ``"exif"`` / ``"prior"`` (they did not; the value is the start's).
    determined : bool
        The photos determined the focal length at least as well as the prior did
        (``data_sigma_log <= start_sigma_log``), or well enough
        (``SelfCalibrationSettings.max_trusted_sigma_log``) to overrule an EXIF value
        they contradict by more than three sigmas; when not, ``K`` keeps the prior's.
    data_focal_px, data_sigma_log : float
        What the photos alone call for, and its standard deviation in ``log f``
        (``uncertainty.total``; inf when the fit could not tell).
    uncertainty : FocalUncertainty
        Its parts: the fit's, the jackknife's and the principal point's.
    start_focal_px, start_sigma_log : float
        The prior it started from.
    geometry : TwoViewGeometry
        The two-view estimate under ``K``; its ``pose_covariance``,
        ``rotation_sigma_deg``, ``translation_sigma_deg`` and ``depth_sigmas`` are
        marginal over the focal length and the principal point
        (:func:`marginal_pose_covariance`), not conditional on ``K``; its ``trusted``
        and ``warnings`` are the two-view pipeline's under ``K``.
    profile : FocalProfile
        The profile the starting basins came from.
    candidates : tuple[tuple[float, float], ...]
        ``(focal_px, cost)`` of each basin's converged fit, the chosen first.
    iterations : int
        Two-view estimates run while iterating (all basins).
    warnings : tuple[str, ...]
        Doubts about the focal length (the geometry's own are in
        ``geometry.warnings``).
    trusted : bool
        ``geometry.trusted``, and the focal length known to
        ``SelfCalibrationSettings.max_trusted_sigma_log`` (so not resting on the
        default prior alone), no other focal length fitting about as well (another
        basin, or a rival, :func:`focal_rivals`), the photos not contradicting an EXIF
        value (by more than three sigmas), and the pose certain enough for
        ``TwoViewSettings`` (``uncertainty_sigmas`` of its marginal sigmas within
        ``uncertainty_limit_deg``).
    seconds : float
        Time spent.
    """

    K: FloatArray
    focal_px: float
    focal_sigma_px: float
    source: str
    determined: bool
    data_focal_px: float
    data_sigma_log: float
    uncertainty: FocalUncertainty
    start_focal_px: float
    start_sigma_log: float
    geometry: TwoViewGeometry
    profile: FocalProfile
    candidates: tuple[tuple[float, float], ...]
    iterations: int
    warnings: tuple[str, ...] = ()
    trusted: bool = True
    seconds: float = 0.0


def with_focal(K: FloatArray, focal_px: float) -> FloatArray:
    """``K`` ``(3, 3)`` with both focal lengths set to ``focal_px`` (principal point kept)."""
    K = np.array(K, dtype=np.float64)
    K[0, 0] = K[1, 1] = focal_px
    return K


def focal_profile(pts1: FloatArray, pts2: FloatArray, K: FloatArray, factors: FloatArray,
                  threshold_px: float, min_threshold_px: float,
                  min_inliers: int = 15) -> FocalProfile:
    """The robust cost of the best pose at focal lengths ``K[0, 0] * factors``.

    At each focal length one robust estimation of E with local optimisation
    (:func:`scene3D.epipolar.fit_essential`, one start: the profile only has to
    find the basins). Each fit is scored over all matches ``pts1, pts2`` ``(N, 2)``
    by :func:`scene3D.epipolar.essential_cost` at one threshold for all: three
    times the smallest robust noise sigma of their inliers (the fit nearest the
    truth has the least spread), at least ``min_threshold_px`` and at most
    ``threshold_px``. Pixels, and so the costs, are comparable across focal lengths.
    """
    focal = K[0, 0] * np.asarray(factors, dtype=np.float64)
    fits, noise = [], []
    for f in focal:
        K_f = with_focal(K, f)
        fit = fit_essential(pts1, pts2, K_f, threshold_px, max_starts=1)
        fits.append(fit)
        if np.all(np.isfinite(fit.E)) and fit.inliers.sum() >= min_inliers:
            noise.append(noise_sigma_px(essential_distances(
                fit.E, pts1[fit.inliers], pts2[fit.inliers], K_f)))
    sigma = min(noise) if noise else threshold_px / 3.0
    threshold = float(np.clip(3.0 * sigma, min_threshold_px, threshold_px))
    cost = np.array([essential_cost(fit.E, pts1, pts2, with_focal(K, f), threshold)
                     if np.all(np.isfinite(fit.E)) and fit.inliers.sum() >= min_inliers
                     else np.inf for f, fit in zip(focal, fits)])
    essentials = np.array([fit.E if np.all(np.isfinite(fit.E)) else np.full((3, 3), np.nan)
                           for fit in fits])
    return FocalProfile(focal, cost, threshold, float(sigma), essentials)


def converge_focal(pts1: FloatArray, pts2: FloatArray, K: FloatArray,
                   settings: TwoViewSettings, max_iterations: int,
                   tolerance_log: float) -> tuple[TwoViewGeometry, int, bool]:
    """Re-run the two-view estimate under the focal length it calls for, until it stops moving.

    Each round is a full :func:`scene3D.twoview.reconstruct_from_matches` (robust E
    under the current ``K``, so the inliers are re-selected, then the focal fit);
    its ``focal_scale`` gives the next focal length. Returns the last geometry (whose
    ``K`` is the one it was estimated with), the rounds run and whether the change
    fell below ``tolerance_log``.

    Raises
    ------
    ReconstructionError
        The pair is refused under some ``K`` of the way.
    """
    for rounds in range(1, max_iterations + 1):
        geometry = reconstruct_from_matches(pts1, pts2, K, settings)
        step = math.log(geometry.focal_scale)
        if abs(step) < tolerance_log:
            return geometry, rounds, True
        if rounds < max_iterations:
            K = with_focal(K, K[0, 0] * geometry.focal_scale)
    return geometry, max_iterations, False


def image_cells(pts: FloatArray, cells: int = 3) -> np.ndarray:
    """The cell ``(N,) int`` of each pixel ``(N, 2)`` among ``cells`` x ``cells`` equal
    cells of the points' bounding box."""
    lo, hi = pts.min(axis=0), pts.max(axis=0)
    cell = np.minimum(((pts - lo) / np.maximum(hi - lo, 1e-9) * cells).astype(int), cells - 1)
    return cell[:, 0] * cells + cell[:, 1]


def blocked_difference_z(differences: ArrayLike, blocks: ArrayLike) -> float:
    """How significant a summed difference is when its terms are correlated within blocks.

    ``differences`` ``(N,)`` are per-match differences of two models' costs (the
    rival's minus the chosen one's), ``blocks`` ``(N,) int`` the cell of each match.
    Matches on one facade, one repeated window pattern or one cluster of wrong matches
    err together, so the standard error of the sum is measured from the ``g`` block
    sums ``D_b``: ``se^2 = g / (g - 1) * sum (D_b - mean D_b)^2``. Returns
    ``sum / se``: small (below about 2) when the data do not tell the two models apart;
    inf when fewer than three blocks hold matches.
    """
    d = np.asarray(differences, dtype=np.float64)
    b = np.asarray(blocks)
    sums = np.array([d[b == k].sum() for k in np.unique(b)])
    g = len(sums)
    if g < 3:
        return math.inf
    se = math.sqrt(g / (g - 1) * float(np.sum((sums - sums.mean()) ** 2)))
    total = float(sums.sum())
    return total / se if se > 0 else (math.inf if total > 0 else -math.inf)


class Rival(NamedTuple):
    """Another focal length whose fit the matches do not tell apart from the chosen one.

    Attributes
    ----------
    focal_px : float
        Its focal length (a point of the profile, or another basin's converged value).
    z : float
        :func:`blocked_difference_z` of its cost over the chosen fit's.
    pose_difference_deg : float
        The larger of the rotation angle and the translation-direction angle between
        its pose and the chosen one.
    """

    focal_px: float
    z: float
    pose_difference_deg: float


def focal_rivals(pts1: FloatArray, pts2: FloatArray, chosen: TwoViewGeometry,
                 focal_px: float, sigma_log: float,
                 fits: list[tuple[float, FloatArray]], threshold_px: float,
                 max_z: float, cells: int = 3) -> list[Rival]:
    """The fits at other focal lengths that fit the matches about as well.

    ``fits`` are ``(focal_px, E)`` pairs (the profile's points and the other basins'
    converged fits), ``chosen`` the selected geometry (focal length ``focal_px``,
    known to ``sigma_log`` by the local analysis). A fit is a rival when its focal
    length lies more than three ``sigma_log`` away (so the local sigma does not
    describe it), its cost over all matches ``pts1, pts2`` ``(N, 2)``
    (:func:`scene3D.epipolar.essential_costs` at ``threshold_px``) is not
    significantly higher (:func:`blocked_difference_z` below ``max_z``, with
    ``cells`` x ``cells`` cells of image 1 as blocks): the local sigma describes only
    one of the answers the pair supports (a facade with repeated windows at 768 px:
    castle-P19 14-15, 15-16, 16-17 ended 6 to 10 deg off with the focal length 20 to
    28 % off and its sigma 2 to 3 %). Each rival's pose is decomposed with cheirality
    on its inliers and compared with the chosen one (``Rival.pose_difference_deg``).
    """
    base = essential_costs(chosen.E, pts1, pts2, chosen.K, threshold_px)
    blocks = image_cells(pts1, cells)
    rivals = []
    for focal, E in fits:
        if (not np.all(np.isfinite(E))
                or abs(math.log(focal / focal_px)) <= 3.0 * sigma_log):
            continue
        K_f = with_focal(chosen.K, focal)
        z = blocked_difference_z(essential_costs(E, pts1, pts2, K_f, threshold_px) - base,
                                 blocks)
        if z >= max_z:
            continue
        inliers = essential_distances(E, pts1, pts2, K_f) <= threshold_px
        if inliers.sum() < 6:
            continue
        R, t, _, _ = choose_pose(E, pts1[inliers], pts2[inliers], K_f)
        difference = max(rotation_error_deg(R, chosen.R), angle_between_deg(t, chosen.t))
        rivals.append(Rival(float(focal), z, difference))
    return rivals


def focal_uncertainty(geometry: TwoViewGeometry, settings: TwoViewSettings,
                      principal_point_shift_px: float, cells: int = 3) -> FocalUncertainty:
    """How well the pair's inliers determine the focal length of ``geometry.K``.

    The focal fit (:func:`scene3D.refinement.fit_focal_scale` on the geometry's
    inliers, from its pose, under the pipeline's noise-adaptive Cauchy loss) is
    repeated (a) without the inliers of each of ``cells`` x ``cells`` cells of
    image 1's bounding box in turn (the delete-a-group jackknife:
    ``var = (g - 1) / g * sum (theta_i - mean)^2``) and (b) with the principal
    point moved by ``principal_point_shift_px`` in x, then in y. See
    :class:`FocalUncertainty`.
    """
    K, in1, in2 = geometry.K, geometry.inlier_pts1, geometry.inlier_pts2
    if len(in1) < 6:
        return FocalUncertainty(math.inf, math.inf, 0.0)
    scale = loss_scale_px(essential_distances(geometry.E, in1, in2, K), settings.threshold_px)

    def fit(p1: FloatArray, p2: FloatArray, K_fit: FloatArray) -> float:
        # Levenberg-Marquardt rejects the non-finite trial steps a far-off start can give.
        with np.errstate(over="ignore", invalid="ignore"):
            return math.log(fit_focal_scale(geometry.R, geometry.t, p1, p2, K_fit, "cauchy",
                                            scale).scale)

    base = fit_focal_scale(geometry.R, geometry.t, in1, in2, K, "cauchy", scale)
    cell_id = image_cells(in1, cells)
    estimates = []
    for c in np.unique(cell_id):
        keep = cell_id != c
        if keep.sum() >= max(20, len(in1) // 4):
            estimates.append(fit(in1[keep], in2[keep], K))
    g = len(estimates)
    jackknife = (math.sqrt((g - 1) / g * float(np.sum((np.array(estimates)
                                                        - np.mean(estimates)) ** 2)))
                 if g >= 3 else math.inf)
    shifts = [0.0, 0.0]
    if principal_point_shift_px > 0:
        for axis in (0, 1):
            K_moved = K.copy()
            K_moved[axis, 2] += principal_point_shift_px
            shifts[axis] = fit(in1, in2, K_moved) - math.log(base.scale)
    return FocalUncertainty(base.sigma_log, jackknife, math.hypot(*shifts),
                            (shifts[0], shifts[1]))


def intrinsics_covariance(focal_sigma_log: float, principal_point_sigma_px: float,
                          focal_shifts: tuple[float, float] = (0.0, 0.0),
                          weight: float = 1.0) -> FloatArray:
    """Covariance ``(3, 3)`` of the intrinsics a pair's pose was estimated under.

    The parameters are ``theta = (log f, c_x, c_y)`` (the principal point in
    pixels), as in :func:`scene3D.refinement.pose_intrinsics_sensitivity`. The
    principal point is the image centre, assumed within ``principal_point_sigma_px``
    (each axis, independent) of the true one; ``log f`` is known to
    ``focal_sigma_log``. The fitted focal length moves with the principal point
    (``focal_shifts``: the moves of ``log f`` for a one-sigma shift along x and
    along y, :attr:`FocalUncertainty.principal_point_shifts`), so their errors are
    correlated: ``cov(log f, c_x) = weight * shift_x * sigma_pp``. ``weight`` is the
    photos' share of a focal length combined with a prior
    (``sigma_combined^2 / sigma_photos^2``; 0 when the value is the prior's).
    """
    sigma_pp = principal_point_sigma_px
    cov = np.diag([focal_sigma_log**2, sigma_pp**2, sigma_pp**2])
    for axis in (0, 1):
        cov[0, axis + 1] = cov[axis + 1, 0] = weight * focal_shifts[axis] * sigma_pp
    return cov


def marginal_pose_covariance(geometry: TwoViewGeometry, intrinsics_cov: FloatArray,
                             settings: TwoViewSettings) -> FloatArray:
    """The pose covariance ``(5, 5)`` of ``geometry`` with its intrinsics' uncertainty added.

    ``geometry.pose_covariance`` is conditional on ``geometry.K``: it describes the
    noise of the matches as if ``K`` were exact. Without a calibration the focal
    length and the principal point are estimates and guesses, and a pose estimated
    under a focal length 20 % off is off by degrees while its conditional sigma says
    hundredths. The marginal covariance adds how the pose moves with the intrinsics
    (:func:`scene3D.refinement.pose_intrinsics_sensitivity`, on the geometry's
    inliers under the loss of its refinement) times their covariance
    ``intrinsics_cov`` ``(3, 3)`` over ``(log f, c_x, c_y)``
    (:func:`intrinsics_covariance`; :func:`scene3D.uncertainty.marginal_covariance`).
    Parametrisation and frames of :mod:`scene3D.uncertainty` (rotation vector in the
    camera-2 frame, then the direction step along ``tangent_basis(geometry.t)``).
    """
    in1, in2, K = geometry.inlier_pts1, geometry.inlier_pts2, geometry.K
    if len(in1) < 6:
        return np.full((5, 5), np.inf)
    scale = loss_scale_px(essential_distances(geometry.E, in1, in2, K), settings.threshold_px)
    sensitivity = pose_intrinsics_sensitivity(geometry.R, geometry.t, in1, in2, K, "cauchy",
                                              scale)
    return marginal_covariance(geometry.pose_covariance, sensitivity, intrinsics_cov)


def _deg(angle: float) -> str:
    """An angle in degrees to two significant digits below 1: '112.3', '2.4', '0.31'."""
    return f"{angle:.1f}" if angle >= 1 else f"{angle:.2g}"


def _main_doubt(uncertainty: FocalUncertainty) -> str:
    """What limits the focal length most, in words."""
    parts = {"little rotation, or optical axes that meet": uncertainty.fit,
             "it rests on one part of the scene": uncertainty.jackknife,
             "the principal point is unknown": uncertainty.principal_point}
    return max(parts, key=lambda k: parts[k] if math.isfinite(parts[k]) else math.inf)


def combine_log_normal(focal1: float, sigma1: float, focal2: float,
                       sigma2: float) -> tuple[float, float]:
    """Inverse-variance combination of two focal lengths known to ``sigma`` in ``log f``.

    Returns ``(focal, sigma_log)``. An infinite sigma contributes nothing.
    """
    w1 = 0.0 if not math.isfinite(sigma1) else 1.0 / sigma1**2
    w2 = 0.0 if not math.isfinite(sigma2) else 1.0 / sigma2**2
    if w1 + w2 == 0.0:
        return focal1, math.inf
    log_f = (w1 * math.log(focal1) + w2 * math.log(focal2)) / (w1 + w2)
    return math.exp(log_f), 1.0 / math.sqrt(w1 + w2)


def _search_factors(prior_sigma_log: float, s: SelfCalibrationSettings) -> FloatArray:
    half = max(s.search_sigmas * prior_sigma_log, math.log(s.min_search_factor))
    steps = max(2, math.ceil(2.0 * half / math.log(s.search_step)))
    return np.exp(np.linspace(-half, half, steps + 1))


def self_calibrate_pair(
    pts1: ArrayLike,
    pts2: ArrayLike,
    K_start: ArrayLike,
    prior_sigma_log: float,
    prior_source: str = "prior",
    settings: TwoViewSettings | None = None,
    search: SelfCalibrationSettings | None = None,
) -> SelfCalibration:
    """The focal length of a pair of photos from one camera, and the pair's geometry under it.

    Parameters
    ----------
    pts1, pts2 : (N, 2) array_like
        Matched pixels in image 1 and image 2 (working images).
    K_start : (3, 3) array_like
        The starting intrinsics of the working images: the prior's focal length and
        principal point (:class:`scene3D.intrinsics_prior.FocalPrior`, scaled to the
        working size). Only the focal length changes.
    prior_sigma_log : float
        Standard deviation of the prior's ``log f``.
    prior_source : str
        ``"exif"`` or ``"prior"``: names the result's ``source``.
    settings : TwoViewSettings, optional
        The two-view pipeline's thresholds.
    search : SelfCalibrationSettings, optional
        The self-calibration's.

    Returns
    -------
    SelfCalibration

    Raises
    ------
    ReconstructionError
        The pair is refused under every focal length tried (too few matches, no
        parallax, ...), with the reason found at the prior's focal length.
    ValueError
        Bad input shapes, or a ``prior_source`` other than ``"exif"`` / ``"prior"``.
    """
    t0 = time.perf_counter()
    s = search or SelfCalibrationSettings()
    tv = settings or TwoViewSettings()
    if prior_source not in ("exif", "prior"):
        raise ValueError(f"`prior_source` must be 'exif' or 'prior', got {prior_source!r}")
    p1, p2 = as_points2d(pts1, "pts1"), as_points2d(pts2, "pts2")
    check_same_length(p1, p2)
    K0 = as_matrix(K_start, (3, 3), "K_start")
    f0 = float(K0[0, 0])
    if len(p1) < tv.min_matches:
        raise ReconstructionError("too_few_matches", "too few matches between the images",
                                  matches=len(p1), required=tv.min_matches)

    profile = focal_profile(p1, p2, K0, _search_factors(prior_sigma_log, s), tv.threshold_px,
                            s.min_noise_threshold * tv.threshold_px, tv.min_inliers)
    starts = [float(profile.focal_px[i]) for i in profile.basins()[:s.max_candidates]]
    if prior_source == "exif" or not starts:
        starts.append(f0)
    # Converge from each basin; basins that end at the same focal length count once.
    runs: list[tuple[float, TwoViewGeometry]] = []
    iterations, refusal = 0, None
    for start in starts:
        if any(abs(math.log(start / g.K[0, 0])) < 3 * s.tolerance_log for _, g in runs):
            continue
        try:
            geometry, rounds, converged = converge_focal(p1, p2, with_focal(K0, start), tv,
                                                         s.max_iterations, s.tolerance_log)
        except ReconstructionError as exc:
            refusal = refusal or exc
            continue
        iterations += rounds
        if not converged:
            logger.debug("focal iteration from %.1f px did not settle", start)
        if any(abs(math.log(geometry.K[0, 0] / g.K[0, 0])) < 0.005 for _, g in runs):
            continue
        runs.append((essential_cost(geometry.E, p1, p2, geometry.K, profile.threshold_px),
                     geometry))
    if not runs:
        # Say why under the prior's own focal length, as a calibrated run would.
        reconstruct_from_matches(p1, p2, K0, tv)
        raise refusal  # type: ignore[misc]
    runs.sort(key=lambda run: run[0])
    best_cost, best = runs[0]

    f_data = float(best.K[0, 0] * best.focal_scale)
    longer_side = 2.0 * max(K0[0, 2], K0[1, 2]) + 1.0  # the principal point is the centre
    uncertainty = focal_uncertainty(best, tv, s.principal_point_sigma * longer_side,
                                    s.jackknife_cells)
    sigma_data = uncertainty.total
    warnings: list[str] = []
    # The photos refine the start when they know the focal length at least as well.
    determined = sigma_data <= prior_sigma_log
    ambiguous = [g for c, g in runs[1:] if c - best_cost < s.ambiguity_cost
                 and abs(math.log(g.K[0, 0] / f_data)) > 3.0 * sigma_data]
    rivals = focal_rivals(
        p1, p2, best, f_data, sigma_data,
        [(float(f), E) for f, E in zip(profile.focal_px, profile.essentials)]
        + [(float(g.K[0, 0]), g.E) for _, g in runs[1:]],
        profile.threshold_px, s.rival_z, s.jackknife_cells)
    pose_rivals = [r for r in rivals if r.pose_difference_deg > tv.uncertainty_limit_deg]
    # Photos and EXIF that disagree beyond their sigmas: one of them is wrong. An EXIF
    # value can be wrong outright (a cropped or resized copy, digital zoom), so beyond
    # three sigmas photos that know the focal length well enough overrule it (the
    # Gaussian combination assumes neither is); the result is doubted either way.
    disagree = prior_source == "exif" and abs(math.log(f_data / f0)) > 3.0 * math.hypot(
        sigma_data, prior_sigma_log)
    if disagree and sigma_data <= s.max_trusted_sigma_log:
        determined = True
        focal, sigma, source = f_data, sigma_data, "exif+refined"
        warnings.append(
            f"the photos call for a focal length {f_data / f0:.2f} times the EXIF one "
            f"(+-{sigma_data:.0%}): cropped or resized photos, digital zoom, or matches that "
            f"mislead? Using the photos' {focal:.1f} px")
    elif determined:
        focal, sigma = combine_log_normal(f_data, sigma_data, f0, prior_sigma_log)
        source = f"{prior_source}+refined"
    else:
        focal, sigma, source = f0, prior_sigma_log, prior_source
        rests_on = ("the EXIF value" if prior_source == "exif" else
                    "the default prior (1.2 x the longer side)")
        warnings.append(f"the photos do not determine the focal length better than "
                        f"{rests_on} (they fit {f_data:.1f} px +-{min(sigma_data, 9.99):.0%}, "
                        f"{_main_doubt(uncertainty)}): kept it")
        if disagree:
            warnings.append(f"the photos call for a focal length {f_data / f0:.2f} times the "
                            "EXIF one: the EXIF value may be wrong")
    if determined and rivals:
        # The focal lengths the matches do not tell apart bound what is known of it.
        sigma = max(sigma, max(abs(math.log(r.focal_px / f_data)) for r in rivals))
    if sigma > s.max_trusted_sigma_log:
        known = (f"+-{sigma:.0%}" if sigma < 0.5 else f"a factor of {math.exp(sigma):.1f}")
        warnings.append(f"the focal length ({focal:.1f} px) is known only to {known}: "
                        "the pose may be off by degrees")
    if ambiguous:
        other = ", ".join(f"{g.K[0, 0]:.1f} px" for g in ambiguous)
        warnings.append(f"other focal lengths fit the matches about as well ({other} against "
                        f"{f_data:.1f} px): the focal length, and the pose, may be wrong")
    if pose_rivals:
        worst_rival = max(pose_rivals, key=lambda r: r.pose_difference_deg)
        warnings.append(
            f"the matches do not tell {f_data:.1f} px from {worst_rival.focal_px:.1f} px "
            f"(cost difference {worst_rival.z:.1f} standard errors), whose pose differs by "
            f"{worst_rival.pose_difference_deg:.1f} deg: the focal length, and the pose, may "
            "be wrong" + (f" ({len(pose_rivals)} such focal lengths)"
                          if len(pose_rivals) > 1 else ""))
    geometry = best
    if abs(math.log(focal / best.K[0, 0])) >= s.tolerance_log:
        geometry = reconstruct_from_matches(p1, p2, with_focal(K0, focal), tv)
        iterations += 1
    # The pose's uncertainty with the focal length's and the principal point's added.
    weight = (0.0 if not determined or not math.isfinite(sigma_data)
              else min(1.0, (sigma / sigma_data) ** 2))
    pp_sigma = (s.principal_point_sigma * longer_side if s.pose_principal_point else 0.0)
    covariance = marginal_pose_covariance(
        geometry, intrinsics_covariance(sigma, pp_sigma, uncertainty.principal_point_shifts,
                                        weight), tv)
    geometry = replace(
        geometry, pose_covariance=covariance,
        rotation_sigma_deg=largest_sigma_deg(covariance[:3, :3]),
        translation_sigma_deg=largest_sigma_deg(covariance[3:, 3:]),
        depth_sigmas=depth_sigmas(geometry.points3d, geometry.K, geometry.R, geometry.t,
                                  covariance, geometry.noise_sigma_px))
    worst = max(geometry.rotation_sigma_deg, geometry.translation_sigma_deg)
    uncertain = worst * tv.uncertainty_sigmas > tv.uncertainty_limit_deg
    if uncertain:
        warnings.append(
            f"uncertain pose once the focal length's and the principal point's uncertainty "
            f"is included: translation direction +-{_deg(geometry.translation_sigma_deg)} deg, "
            f"rotation +-{_deg(geometry.rotation_sigma_deg)} deg (1 sigma), more than "
            f"{tv.uncertainty_limit_deg:g} deg at {tv.uncertainty_sigmas:g} sigma")
    trusted = (geometry.trusted and not ambiguous and not pose_rivals and not disagree
               and not uncertain and sigma <= s.max_trusted_sigma_log)
    return SelfCalibration(
        K=geometry.K, focal_px=float(geometry.K[0, 0]), focal_sigma_px=focal * sigma,
        source=source, determined=determined, data_focal_px=f_data,
        data_sigma_log=sigma_data, uncertainty=uncertainty,
        start_focal_px=f0, start_sigma_log=prior_sigma_log, geometry=geometry,
        profile=profile, candidates=tuple((float(g.K[0, 0]), float(c)) for c, g in runs),
        iterations=iterations, warnings=tuple(warnings), trusted=trusted,
        seconds=time.perf_counter() - t0)
