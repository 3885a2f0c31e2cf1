"""How sure a self-calibrated focal length is, which other focal lengths the matches
do not tell apart, and the pose covariance marginal over the intrinsics (see
:mod:`scene3D.selfcalibration`; the pose's own covariance is :mod:`scene3D.optim.uncertainty`)."""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np
from numpy.typing import ArrayLike

from ..geometry.conventions import FloatArray, pose_angle_deg
from ..geometry.epipolar import essential_distances
from ..geometry.pose import choose_pose
from ..optim.refinement import pose_intrinsics_sensitivity
from ..optim.uncertainty import marginal_covariance
from ..twoview import TwoViewGeometry, TwoViewSettings
from ..twoview.essential_fit import essential_costs, loss_scale_px
from ..twoview.focal_fit import fit_focal_scale
from .search import with_focal


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


def image_cells(pts: FloatArray, cells: int = 3) -> np.ndarray:
    """The cell ``(N,) int`` of each pixel ``(N, 2)`` among ``cells`` x ``cells`` equal
    cells of the points' bounding box.

    Parameters
    ----------
    pts : (N, 2) ndarray
        Pixels.
    cells : int, default 3
        Cells per side.

    Returns
    -------
    (N,) int ndarray
    """
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

    Parameters
    ----------
    differences : (N,) array_like
        Per-match cost differences.
    blocks : (N,) int array_like
        Block of each match.

    Returns
    -------
    float
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
    (:func:`scene3D.twoview.essential_fit.essential_costs` at ``threshold_px``) is not
    significantly higher (:func:`blocked_difference_z` below ``max_z``, with
    ``cells`` x ``cells`` cells of image 1 as blocks): the local sigma describes only
    one of the answers the pair supports (a facade with repeated windows; see
    docs/benchmarks.md#self-calibration-trust-that-is-not-fooled). Each rival's pose is
    decomposed with cheirality on its inliers and compared with the chosen one
    (``Rival.pose_difference_deg``).

    Parameters
    ----------
    pts1, pts2 : (N, 2) ndarray
        All the matches (pixels).
    chosen : TwoViewGeometry
        The selected geometry.
    focal_px : float
        Its focal length (px).
    sigma_log : float
        Its standard deviation in ``log f``.
    fits : list of (float, (3, 3) ndarray)
        ``(focal_px, E)`` of the other fits.
    threshold_px : float
        Scoring threshold (px).
    max_z : float
        Largest :func:`blocked_difference_z` of a rival.
    cells : int, default 3
        Cells per side of the blocks.

    Returns
    -------
    list of Rival
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
        difference = pose_angle_deg(R, t, chosen.R, chosen.t)
        rivals.append(Rival(float(focal), z, difference))
    return rivals


def focal_uncertainty(geometry: TwoViewGeometry, settings: TwoViewSettings,
                      principal_point_shift_px: float, cells: int = 3) -> FocalUncertainty:
    """How well the pair's inliers determine the focal length of ``geometry.K``.

    The focal fit (:func:`scene3D.twoview.focal_fit.fit_focal_scale` on the geometry's
    inliers, from its pose, under the pipeline's noise-adaptive Cauchy loss) is
    repeated (a) without the inliers of each of ``cells`` x ``cells`` cells of
    image 1's bounding box in turn (the delete-a-group jackknife:
    ``var = (g - 1) / g * sum (theta_i - mean)^2``) and (b) with the principal
    point moved by ``principal_point_shift_px`` in x, then in y. See
    :class:`FocalUncertainty`.

    Parameters
    ----------
    geometry : TwoViewGeometry
        The pair's geometry.
    settings : TwoViewSettings
        Gives ``threshold_px``.
    principal_point_shift_px : float
        Assumed principal point error (px).
    cells : int, default 3
        Cells per side of the jackknife.

    Returns
    -------
    FocalUncertainty
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
    pixels), as in :func:`scene3D.optim.refinement.pose_intrinsics_sensitivity`. The
    principal point is the image centre, assumed within ``principal_point_sigma_px``
    (each axis, independent) of the true one; ``log f`` is known to
    ``focal_sigma_log``. The fitted focal length moves with the principal point
    (``focal_shifts``: the moves of ``log f`` for a one-sigma shift along x and
    along y, :attr:`FocalUncertainty.principal_point_shifts`), so their errors are
    correlated: ``cov(log f, c_x) = weight * shift_x * sigma_pp``. ``weight`` is the
    photos' share of a focal length combined with a prior
    (``sigma_combined^2 / sigma_photos^2``; 0 when the value is the prior's).

    Parameters
    ----------
    focal_sigma_log : float
        Standard deviation of ``log f``.
    principal_point_sigma_px : float
        Standard deviation of each principal point coordinate (px).
    focal_shifts : (float, float), default (0.0, 0.0)
        Moves of ``log f`` for a one-sigma principal point shift along x and y.
    weight : float, default 1.0
        The photos' share of the focal length.

    Returns
    -------
    (3, 3) float64 ndarray
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
    (:func:`scene3D.optim.refinement.pose_intrinsics_sensitivity`, on the geometry's
    inliers under the loss of its refinement) times their covariance
    ``intrinsics_cov`` ``(3, 3)`` over ``(log f, c_x, c_y)``
    (:func:`intrinsics_covariance`; :func:`scene3D.optim.uncertainty.marginal_covariance`).
    Parametrisation and frames of :mod:`scene3D.optim.uncertainty` (rotation vector in the
    camera-2 frame, then the direction step along ``tangent_basis(geometry.t)``).

    Parameters
    ----------
    geometry : TwoViewGeometry
        The pair's geometry (``x_cam2 = R x_cam1 + t``).
    intrinsics_cov : (3, 3) ndarray
        Covariance of ``(log f, c_x, c_y)``.
    settings : TwoViewSettings
        Gives ``threshold_px``.

    Returns
    -------
    (5, 5) float64 ndarray
    """
    in1, in2, K = geometry.inlier_pts1, geometry.inlier_pts2, geometry.K
    if len(in1) < 6:
        return np.full((5, 5), np.inf)
    scale = loss_scale_px(essential_distances(geometry.E, in1, in2, K), settings.threshold_px)
    sensitivity = pose_intrinsics_sensitivity(geometry.R, geometry.t, in1, in2, K, "cauchy",
                                              scale)
    return marginal_covariance(geometry.pose_covariance, sensitivity, intrinsics_cov)
