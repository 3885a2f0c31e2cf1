"""The robust essential matrix: restarts, local optimisation and noise-adaptive thresholds.

:func:`fit_essential` runs a robust USAC estimation (5-point solver) and a local
optimisation of the pose on its inliers (:func:`refine_essential`: the Sampson
refinement of :func:`scene3D.optim.refinement.refine_relative_pose` under a Cauchy loss
whose scale follows the keypoints' noise), restarted until the best fit repeats, the
starts' optima compared by a robust cost (:func:`essential_cost`) at the noise of the
keypoints. The relations it builds on (Sampson distances, ``E`` from a pose, ``F``
from ``E``) and the robust ``F`` and ``H`` are in :mod:`scene3D.geometry.epipolar`.

Conventions: ``x2^T F x1 = 0`` with pixel coordinates, ``E = [t]x R`` with
``x_cam2 = R x_cam1 + t`` (Hartley & Zisserman, sections 9.2 and 9.6).
"""

from __future__ import annotations

import random
import time
from typing import NamedTuple

import cv2
import numpy as np
from numpy.typing import ArrayLike

from ..geometry.camera import validate_intrinsics
from ..geometry.conventions import FloatArray, distinct_correspondences, median, pose_angle_deg
from ..geometry.epipolar import (
    ROBUST_METHOD,
    check_correspondences,
    essential_distances,
    essential_from_pose,
    inlier_mask,
)
from ..geometry.pose import decompose_essential, nearest_decomposition
from ..optim.least_squares import robust_loss
from ..optim.refinement import refine_relative_pose, relative_pose_covariance
from ..optim.uncertainty import CHI2_99_POSE, pose_difference_chi2

#: Robust estimator of the restarts of :func:`fit_essential` when they run below the
#: given threshold: USAC with MSAC scoring and local optimisation (LO-RANSAC). At a
#: threshold near the noise it keeps the tightest consensus; MAGSAC++ marginalises over
#: noise levels up to the threshold and, on repeated structure, returns the model that
#: also fits the mismatches more loosely. At the given threshold (matches as noisy as it
#: allows) the restarts use :data:`scene3D.geometry.epipolar.ROBUST_METHOD`, which suits noise of
#: that size better.
RESTART_METHOD = cv2.USAC_DEFAULT

#: Scale of the Cauchy loss of the MSAC-style cost that compares models, as a fraction
#: of the inlier threshold (the threshold taken as about three standard deviations of
#: keypoint noise): one fixed scale, so that models fitted to different inliers compare.
LOSS_SCALE_OF_THRESHOLD = 1.0 / 3.0

#: Scale of the local optimisation's Cauchy loss in standard deviations of the noise:
#: 2.385 sigma keeps 95 % of least squares' efficiency under Gaussian noise (Holland
#: and Welsch, 1977) and still discounts the heavy tail of real matches.
CAUCHY_SCALE_OF_SIGMA = 2.385

#: Inlier threshold in standard deviations of the noise, when the noise is larger than
#: the given threshold assumes, and how far it may be raised (times the given one).
THRESHOLD_OF_SIGMA = 3.0
MAX_THRESHOLD_GROWTH = 2.0

#: The restarts of :func:`fit_essential` first probe the keypoint noise with a robust
#: estimation at this fraction of the inlier threshold, and compare their optima at
#: :data:`THRESHOLD_OF_SIGMA` times that noise, never below this fraction of the threshold
#: (:func:`comparison_threshold_px`). The default 1 px threshold leaves room for noise
#: of a third of a pixel; bias-free SIFT keypoints have 0.06-0.32 px (fountain-P11,
#: Herz-Jesus-P8 and castle-P19 at 768 and 1536 px).
NOISE_PROBE_OF_THRESHOLD = 0.125

#: Restarts' optima whose robust cost (:func:`essential_cost`, a Cauchy negative
#: log-likelihood up to a constant) exceeds the best by more than this fit the matches
#: measurably worse: half the 99 % quantile of chi-squared with 5 degrees of freedom
#: (those of a relative pose), the likelihood-ratio test. Only the others count in
#: :attr:`EssentialFit.spread_deg`.
COMPARABLE_COST = 0.5 * 15.09


class EssentialFit(NamedTuple):
    """What :func:`fit_essential` found.

    Attributes
    ----------
    E : (3, 3) float64
        Essential matrix with unit Frobenius norm (NaN when none was found).
    inliers : (N,) bool
        Correspondences within the threshold of ``E``.
    starts : int
        Robust estimations run (1 without restarts).
    refinement_s : float
        Seconds spent in the local optimisation (all starts).
    confirmed : bool
        The returned fit was reached from at least two starts (False with one start,
        or when ``max_starts`` ran out first: then several models fit about equally
        well).
    spread_deg : float
        How far the other starts' optima that fit about as well lie from the
        returned one: the largest :func:`essential_angle_deg` between them, over
        the optima whose cost is within :data:`COMPARABLE_COST` of the best (0 with
        one start). Unconfirmed with a small spread, the optima are distinct but the
        pose is still known to that angle; with a large one, it is doubtful. An
        optimum that fits measurably worse (a pose that also fits mismatches of
        repeated structure, say) is no rival.
    comparison_threshold_px : float
        The threshold at which the starts' optima were compared
        (:func:`comparison_threshold_px`; the given threshold with one start).
    rivals : tuple of (3, 3) float64
        The other optima whose cost is within :data:`COMPARABLE_COST` of the best
        (unit norm; those that ``spread_deg`` measures), for a caller to weigh against
        the pose's covariance (:func:`scene3D.twoview.rival_chi2`).
    fitted_threshold_px : float
        The threshold whose inliers ``E`` was refined on and ``inliers`` holds: the given
        one, or ``comparison_threshold_px`` when the matches between the two pull the
        pose out of the region that the covariance of its fit within the noise allows
        (:func:`widening_shift_chi2`).
    widening_shift_chi2 : float
        How far the refinement at the given threshold moved the pose from the optimum
        within the noise (:func:`widening_shift_chi2`; 0 when it was not run: no
        restarts below the threshold, or fewer inliers than the test needs).
    """

    E: FloatArray
    inliers: np.ndarray
    starts: int
    refinement_s: float
    confirmed: bool = False
    spread_deg: float = 0.0
    comparison_threshold_px: float = float("nan")
    rivals: tuple[FloatArray, ...] = ()
    fitted_threshold_px: float = float("nan")
    widening_shift_chi2: float = 0.0


def fit_essential(
    pts1: ArrayLike,
    pts2: ArrayLike,
    K: ArrayLike,
    threshold_px: float = 1.0,
    confidence: float = 0.999,
    max_iters: int = 10000,
    max_starts: int = 16,
    shift_test_min_inliers: int = 50,
) -> EssentialFit:
    """Robust essential matrix with local optimisation, restarted until the best fit repeats.

    Each start is one robust USAC estimation (5-point solver) followed by
    :func:`refine_essential`. With few inliers (wide baselines) or repeated
    structure the robust cost has several local minima and one start can settle
    in a poor one, so the estimation is restarted with other random samples until
    the refined model of lowest cost (:func:`essential_cost`) has been reached from
    two starts, or ``max_starts`` are spent; an easy pair takes two starts. OpenCV's
    USAC seeds its generator the same way on every call, so a restart shuffles the
    correspondences instead (with a fixed seed: the result is repeatable).

    The optima are compared at the noise of the keypoints, not at ``threshold_px``.
    A generous threshold lets a pose that is off by degrees fit two sets of
    matches at once: the right ones, a little worse, and mismatches between
    repeated windows, which lie a few pixels from their true epipolar lines
    (castle-P19 at 1536 px: 700 inliers with a median Sampson distance of 0.26 px,
    1.6 deg off, against 560 inliers at 0.10 px for the true pose). Within the
    noise only the true pose fits. So a noise probe comes first, a USAC estimation at
    :data:`NOISE_PROBE_OF_THRESHOLD` of the threshold, tight enough that no such
    compromise fits within it; the noise of the matches within ``threshold_px`` of
    its model sets the comparison threshold (:func:`comparison_threshold_px`, three
    standard deviations). When that is below ``threshold_px``, the probe is the first
    start, every other start (:data:`RESTART_METHOD`) runs and is refined at that
    threshold, and the best optimum is finally refined at ``threshold_px``, whose
    inliers it returns, unless the matches that this lets in pull the pose out of the
    region that the covariance of the optimum within the noise allows (chi-square of
    the shift, :func:`widening_shift_chi2`, above :data:`scene3D.optim.uncertainty.CHI2_99_POSE`):
    then they are not noise of the same matches but a population of their own, which
    another pose fits (castle-P19 pair 8-9 at 768 px: 2 deg away; mismatched windows half
    a pixel to a pixel off their epipolar lines do the same), and the optimum within the
    noise is returned with its own inliers. Where they agree,
    the wider fit is the more precise one and is kept: a test of the efficient estimate
    against the robust one (Hausman, 1978). When the matches are as noisy as
    ``threshold_px`` allows, the starts are those of a plain restart at ``threshold_px``
    (:data:`scene3D.geometry.epipolar.ROBUST_METHOD`, the first on the matches in their order).

    Parameters
    ----------
    pts1, pts2 : (N, 2) array_like
        Corresponding pixels, N >= 5.
    K : (3, 3) array_like
        Intrinsics of the (working) images.
    threshold_px : float
        Inlier threshold in pixels: the largest distance at which a match counts.
    max_starts : int
        Most starts, each a refined robust estimation (>= 1; 1: a single MAGSAC++
        start at ``threshold_px``, no noise probe and no restarts, as plain OpenCV).
    shift_test_min_inliers : int
        The wider refinement is tested against the fit within the noise only when that
        fit has at least this many inliers (each correspondence once): the test rests on
        its covariance, which fewer residuals leave too uncertain (random subsets of
        25-120 matches of the three Strecha scenes: below 50 such inliers the test
        fired on 13-17 % of the fits and the wider refinement was the nearer to the
        truth twice as often; ``TwoViewSettings.trusted_inliers`` is the same floor).

    Returns
    -------
    EssentialFit
    """
    if max_starts < 1:
        raise ValueError(f"max_starts must be >= 1, got {max_starts}")
    p1, p2 = check_correspondences(pts1, pts2, 5)
    K = validate_intrinsics(K)
    n = len(p1)
    # Python's generator, not numpy's: numpy.random costs 13 ms to import.
    rng = random.Random(0)
    refinement_s = 0.0
    fits: list[tuple[float, FloatArray, np.ndarray]] = []  # (cost, E, inliers)
    tau = threshold_px
    if max_starts > 1:
        E_probe, _ = _robust_essential(p1, p2, K, NOISE_PROBE_OF_THRESHOLD * threshold_px,
                                       confidence, max_iters, method=RESTART_METHOD)
        if np.all(np.isfinite(E_probe)):
            tau = comparison_threshold_px(essential_distances(E_probe, p1, p2, K),
                                          threshold_px)
        if tau < threshold_px:  # the probe is the first start
            t0 = time.perf_counter()
            fits.append(polish_essential(E_probe, p1, p2, K, tau))
            refinement_s += time.perf_counter() - t0
    # Matches as noisy as the threshold allows: the restarts of before, MAGSAC++ at it.
    method = RESTART_METHOD if tau < threshold_px else ROBUST_METHOD
    confirmed = False
    for start in range(len(fits), max_starts):
        order = None if start == 0 else np.array(rng.sample(range(n), n))
        E, inliers = _robust_essential(p1, p2, K, tau, confidence, max_iters, order, method)
        if not np.all(np.isfinite(E)):
            continue
        t0 = time.perf_counter()
        fits.append(polish_essential(E, p1, p2, K, tau, inliers))
        refinement_s += time.perf_counter() - t0
        best_E = min(fits, key=lambda fit: fit[0])[1]
        confirmed = sum(_same_essential(E_, best_E) for _, E_, _ in fits) >= 2
        if confirmed:
            break
    if not fits:
        return EssentialFit(np.full((3, 3), np.nan), np.zeros(n, dtype=bool), max_starts,
                            refinement_s, comparison_threshold_px=tau, fitted_threshold_px=tau)
    best_cost, E, inliers = min(fits, key=lambda fit: fit[0])
    spread = rival_spread_deg([(cost, E_other) for cost, E_other, _ in fits])
    rivals = tuple(E_other for cost, E_other, _ in fits
                   if cost <= best_cost + COMPARABLE_COST and not _same_essential(E_other, E))
    fitted_px, shift_chi2 = tau, 0.0
    if tau < threshold_px:  # the inliers the caller asked for, and the pose they give
        t0 = time.perf_counter()
        _, E_wide, inliers_wide = polish_essential(E, p1, p2, K, threshold_px)
        if len(distinct_correspondences(p1[inliers], p2[inliers])) >= shift_test_min_inliers:
            shift_chi2 = widening_shift_chi2(E, inliers, E_wide, p1, p2, K, tau)
        if shift_chi2 <= CHI2_99_POSE:
            E, inliers, fitted_px = E_wide, inliers_wide, threshold_px
        refinement_s += time.perf_counter() - t0
    return EssentialFit(E, inliers, len(fits), refinement_s, confirmed, spread, tau, rivals,
                        fitted_px, shift_chi2)


def widening_shift_chi2(E: FloatArray, inliers: np.ndarray, E_wide: FloatArray, p1: FloatArray,
                        p2: FloatArray, K: FloatArray, threshold_px: float) -> float:
    """How far a wider threshold's refinement moved a pose, under the pose's covariance.

    ``E`` is the optimum of :func:`polish_essential` at ``threshold_px`` with its
    ``inliers`` ``(N,) bool`` among the correspondences ``p1, p2`` ``(N, 2)``, and
    ``E_wide`` the refinement from it at a wider threshold. Returns the chi-square
    (5 degrees of freedom, :func:`scene3D.optim.uncertainty.pose_difference_chi2`) of
    ``E_wide`` under the sandwich covariance of ``E`` on its inliers
    (:func:`scene3D.optim.refinement.relative_pose_covariance`, the refinement's loss and
    scale; 0 when it is not finite). If the matches the wider threshold lets in were
    the same noise's tail, the wider fit would be the same pose known a little better,
    and its shift would lie well within that covariance (the covariance of the
    difference is smaller still: this is a conservative Hausman test).

    Parameters
    ----------
    E : (3, 3) array_like
        Optimum at ``threshold_px``.
    inliers : (N,) bool ndarray
        Its inliers among ``p1, p2``.
    E_wide : (3, 3) array_like
        Refinement at a wider threshold.
    p1, p2 : (N, 2) array_like
        All the correspondences (pixels, OpenCV convention).
    K : (3, 3) array_like
        Intrinsics shared by both views.
    threshold_px : float
        Inlier threshold on the Sampson distance (px).

    Returns
    -------
    float
    """
    R, t = decompose_essential(E)[0]
    in1, in2 = p1[inliers], p2[inliers]
    scale = loss_scale_px(essential_distances(E, in1, in2, K), threshold_px)
    covariance = relative_pose_covariance(R, t, in1, in2, K, "cauchy", scale)
    return pose_difference_chi2(R, t, *nearest_decomposition(E_wide, R, t), covariance)


def estimate_essential(
    pts1: ArrayLike,
    pts2: ArrayLike,
    K: ArrayLike,
    threshold_px: float = 1.0,
    confidence: float = 0.999,
    max_iters: int = 10000,
    refine: bool = True,
) -> tuple[FloatArray, np.ndarray]:
    """Robustly estimate the essential matrix with the 5-point solver (USAC MAGSAC++).

    Both views share the intrinsics ``K``; E is estimated from calibrated
    points directly, not as ``K^T F K``. With ``refine`` the estimate is then
    polished by minimising Sampson distances over the inliers, which are
    re-selected with the polished model (local optimisation). One start; the
    two-view pipeline uses :func:`fit_essential`, which restarts.

    Parameters as for :func:`fit_essential`.

    Returns
    -------
    E : (3, 3) float64
        Essential matrix with unit Frobenius norm, ``x2n^T E x1n = 0`` for
        normalised coordinates ``xn = K^-1 x``.
    inliers : (N,) bool

    Parameters
    ----------
    pts1, pts2 : (N, 2) array_like
        Corresponding pixels (OpenCV convention), N >= 5.
    K : (3, 3) array_like
        Intrinsics shared by both views.
    threshold_px : float, default 1.0
        Inlier threshold (px).
    confidence : float, default 0.999
        RANSAC confidence.
    max_iters : int, default 10000
        Most RANSAC iterations.
    refine : bool, default True
        Polish the estimate by local optimisation.
    """
    if refine:
        fit = fit_essential(pts1, pts2, K, threshold_px, confidence, max_iters, max_starts=1)
        return fit.E, fit.inliers
    p1, p2 = check_correspondences(pts1, pts2, 5)
    return _robust_essential(p1, p2, validate_intrinsics(K), threshold_px, confidence,
                             max_iters)


def _robust_essential(p1: FloatArray, p2: FloatArray, K: FloatArray, threshold_px: float,
                      confidence: float, max_iters: int, order: np.ndarray | None = None,
                      method: int = ROBUST_METHOD) -> tuple[FloatArray, np.ndarray]:
    """One USAC estimation (``method``), on the correspondences taken in ``order`` (a permutation).

    Returns ``E`` (unit norm; NaN when none was found) and the ``(N,) bool``
    inliers in the original order.
    """
    n = len(p1)
    if order is not None:
        p1, p2 = p1[order], p2[order]
    E, mask = cv2.findEssentialMat(p1, p2, K, method, confidence, threshold_px, max_iters)
    if E is None or E.shape != (3, 3):
        # Several solutions are stacked as (3k, 3) when the solver is not robust.
        return np.full((3, 3), np.nan), np.zeros(n, dtype=bool)
    inliers = np.zeros(n, dtype=bool)
    inliers[np.arange(n) if order is None else order] = inlier_mask(mask, n)
    return E / np.linalg.norm(E), inliers


def essential_costs(E: ArrayLike, pts1: ArrayLike, pts2: ArrayLike, K: ArrayLike,
                    threshold_px: float) -> FloatArray:
    """Each correspondence's share ``(N,)`` of :func:`essential_cost`.

    Parameters
    ----------
    E : (3, 3) array_like
        Essential matrix, ``x2n^T E x1n = 0``.
    pts1, pts2 : (N, 2) array_like
        Matched pixels (OpenCV convention) in images 1 and 2.
    K : (3, 3) array_like
        Intrinsics shared by both views.
    threshold_px : float
        Inlier threshold on the Sampson distance (px).

    Returns
    -------
    (N,) float64 ndarray
    """
    distances = np.minimum(essential_distances(E, pts1, pts2, K), threshold_px)
    scale = LOSS_SCALE_OF_THRESHOLD * threshold_px
    return robust_loss((distances / scale) ** 2, "cauchy")[0]


def essential_cost(E: ArrayLike, pts1: ArrayLike, pts2: ArrayLike, K: ArrayLike,
                   threshold_px: float) -> float:
    """Robust cost of an essential matrix over all correspondences (lower is better).

    A Cauchy loss (scale :data:`LOSS_SCALE_OF_THRESHOLD` of the threshold, the same
    for every model) on the Sampson distances, each capped at the threshold, so
    that an outlier costs the same whatever its distance (an MSAC-style score): it
    compares models that were refined on different inlier sets.

    Parameters
    ----------
    E : (3, 3) array_like
        Essential matrix, ``x2n^T E x1n = 0``.
    pts1, pts2 : (N, 2) array_like
        All the correspondences (pixels).
    K : (3, 3) array_like
        Intrinsics shared by both views.
    threshold_px : float
        Cap of the Sampson distances (px).

    Returns
    -------
    float
    """
    return float(np.sum(essential_costs(E, pts1, pts2, K, threshold_px)))


def polish_essential(E: FloatArray, p1: FloatArray, p2: FloatArray, K: FloatArray,
                     threshold_px: float,
                     inliers: np.ndarray | None = None) -> tuple[float, FloatArray, np.ndarray]:
    """Local optimisation from ``E`` (:func:`refine_essential`), and the result's robust cost.

    ``inliers`` ``(N,) bool`` are the starting inliers among all the correspondences
    ``p1, p2`` (default: those of ``E`` within the threshold). Returns
    ``(cost, E, inliers)`` with ``E`` of unit norm and the cost of :func:`essential_cost`,
    so that models polished from different starts can be compared.

    Parameters
    ----------
    E : (3, 3) array_like
        Start.
    p1, p2 : (N, 2) array_like
        All the correspondences (pixels, OpenCV convention).
    K : (3, 3) array_like
        Intrinsics shared by both views.
    threshold_px : float
        Inlier threshold on the Sampson distance (px).
    inliers : (N,) bool ndarray or None, default None
        Starting inliers; None for those of ``E``.

    Returns
    -------
    cost : float
    E : (3, 3) float64 ndarray
    inliers : (N,) bool ndarray
    """
    if inliers is None:
        inliers = essential_distances(E, p1, p2, K) <= threshold_px
    if inliers.sum() >= 6:
        E, inliers = refine_essential(E, p1, p2, K, inliers, threshold_px)
    E = E / np.linalg.norm(E)
    return essential_cost(E, p1, p2, K, threshold_px), E, inliers


def _same_essential(E1: FloatArray, E2: FloatArray, tolerance: float = 1e-4) -> bool:
    """True when two unit-norm essential matrices agree up to sign (the same local optimum)."""
    return bool(min(np.abs(E1 - E2).max(), np.abs(E1 + E2).max()) < tolerance)


def rival_spread_deg(optima: list[tuple[float, FloatArray]]) -> float:
    """How far apart the optima that fit about equally well lie, in degrees.

    ``optima`` are ``(cost, E)`` pairs of refined starts (costs of
    :func:`essential_cost` at one threshold). Returns the largest
    :func:`essential_angle_deg` between the lowest-cost ``E`` and the others whose
    cost is within :data:`COMPARABLE_COST` of it; 0 when no other is that close.

    Parameters
    ----------
    optima : list of (float, (3, 3) ndarray)
        ``(cost, E)`` of the refined starts.

    Returns
    -------
    float
        Degrees.
    """
    best_cost, best_E = min(optima, key=lambda optimum: optimum[0])
    return max(essential_angle_deg(best_E, E) for cost, E in optima
               if cost <= best_cost + COMPARABLE_COST)


def essential_angle_deg(E1: ArrayLike, E2: ArrayLike) -> float:
    """How far apart the poses of two essential matrices are, in degrees.

    The larger of the rotation angle and the translation-direction angle (up to
    sign) between the nearest of their decompositions
    (:func:`scene3D.geometry.pose.decompose_essential`); 0 for the same matrix up to scale.
    Both rotations of each are tried: the pose and its twisted pair (turned 180 deg
    about the baseline) lie about 180 deg apart, so the minimum pairs like with like.

    Parameters
    ----------
    E1, E2 : (3, 3) array_like
        Essential matrices.

    Returns
    -------
    float
        Degrees.
    """
    poses1 = decompose_essential(E1)
    t1 = poses1[0][1]
    return min(pose_angle_deg(*nearest_decomposition(E2, R1, t1), R1, t1)
               for R1, _ in poses1[::2])


def noise_sigma_px(distances: FloatArray) -> float:
    """Robust standard deviation of the keypoint noise behind inliers' Sampson distances.

    ``distances`` ``(N,)`` are Sampson distances in pixels
    (:func:`scene3D.geometry.epipolar.essential_distances`).
    With Gaussian noise of ``sigma`` px on each coordinate of both images, a Sampson
    distance is ``|N(0, sigma^2)|`` to first order, so ``1.4826`` times their median
    estimates ``sigma`` and ignores the outliers' tail.

    Parameters
    ----------
    distances : (N,) array_like
        Sampson distances (px).

    Returns
    -------
    float
        Noise standard deviation per coordinate (px).
    """
    return 1.4826 * median(np.abs(distances))


def loss_scale_px(distances: FloatArray, threshold_px: float) -> float:
    """Cauchy scale (pixels) for refining a model on inliers with these Sampson distances.

    :data:`CAUCHY_SCALE_OF_SIGMA` times :func:`noise_sigma_px`: the loss follows the
    noise of the images at hand (sharp or blurred, large or small) instead of a fixed
    fraction of the threshold. It is capped at the threshold, and floored at a
    thousandth of it so that noise-free data keep the loss defined.

    Parameters
    ----------
    distances : (N,) array_like
        Inliers' Sampson distances (px).
    threshold_px : float
        Inlier threshold on the Sampson distance (px).

    Returns
    -------
    float
        Cauchy scale (px).
    """
    sigma = noise_sigma_px(distances)
    return float(np.clip(CAUCHY_SCALE_OF_SIGMA * sigma, 1e-3 * threshold_px, threshold_px))


def inlier_threshold_px(distances: FloatArray, threshold_px: float) -> float:
    """Inlier threshold (pixels) for re-selecting inliers whose Sampson distances are these.

    The given threshold, raised to :data:`THRESHOLD_OF_SIGMA` times
    :func:`noise_sigma_px` when the images are noisier than it assumes (a 1 px
    threshold cuts Gaussian noise of 0.5 px at two sigma, and the cut biases the
    fit), and never beyond :data:`MAX_THRESHOLD_GROWTH` times it, so that a set
    of outliers, whose distances spread up to the threshold, cannot widen it
    round after round.

    Parameters
    ----------
    distances : (N,) array_like
        Inliers' Sampson distances (px).
    threshold_px : float
        Inlier threshold on the Sampson distance (px).

    Returns
    -------
    float
        Threshold (px).
    """
    raised = THRESHOLD_OF_SIGMA * noise_sigma_px(distances)
    return float(np.clip(raised, threshold_px, MAX_THRESHOLD_GROWTH * threshold_px))


def comparison_threshold_px(distances: FloatArray, threshold_px: float) -> float:
    """Threshold (pixels) at which :func:`fit_essential` compares its starts' optima.

    ``distances`` ``(N,)`` are the Sampson distances of all correspondences to a
    model fitted within the noise (the noise probe of :func:`fit_essential`); those
    within ``threshold_px`` give the noise (:func:`noise_sigma_px`), and the result
    is :data:`THRESHOLD_OF_SIGMA` times it: the inlier threshold that the noise
    calls for, where a match off by a pixel or two no longer counts. It is kept
    between :data:`NOISE_PROBE_OF_THRESHOLD` times ``threshold_px`` (noise-free
    matches) and ``threshold_px`` (noisier matches than the threshold allows for:
    the threshold is the user's word), and is ``threshold_px`` when fewer than
    five distances lie within it.

    Parameters
    ----------
    distances : (N,) array_like
        Sampson distances (px) of all correspondences.
    threshold_px : float
        Inlier threshold on the Sampson distance (px).

    Returns
    -------
    float
        Threshold (px).
    """
    distances = np.asarray(distances, dtype=np.float64)
    near = distances[distances <= threshold_px]
    if len(near) < 5:
        return float(threshold_px)
    sigma = noise_sigma_px(near)
    return float(np.clip(THRESHOLD_OF_SIGMA * sigma, NOISE_PROBE_OF_THRESHOLD * threshold_px,
                         threshold_px))


def refine_essential(
    E: FloatArray, p1: FloatArray, p2: FloatArray, K: FloatArray, inliers: np.ndarray,
    threshold_px: float, rounds: int = 3,
) -> tuple[FloatArray, np.ndarray]:
    """Local optimisation of an essential matrix: refine on the inliers, re-select, repeat.

    ``p1, p2`` are all the correspondences ``(N, 2)`` and ``inliers`` their
    current ``(N,) bool`` mask; returns the refined ``E`` and the new mask.

    Each round refines under a Cauchy loss whose scale follows the inliers' noise
    under the current model (:func:`loss_scale_px`), so that matches far out in
    the noise's tail weigh little, however noisy the images are; the inliers are
    then re-selected at :func:`inlier_threshold_px`, ``threshold_px`` unless the
    noise calls for more.

    Parameters
    ----------
    E : (3, 3) array_like
        Start.
    p1, p2 : (N, 2) array_like
        All the correspondences (pixels, OpenCV convention).
    K : (3, 3) array_like
        Intrinsics shared by both views.
    inliers : (N,) bool ndarray
        Current inliers.
    threshold_px : float
        Inlier threshold on the Sampson distance (px).
    rounds : int, default 3
        Most refine/re-select rounds.

    Returns
    -------
    E : (3, 3) float64 ndarray
    inliers : (N,) bool ndarray
    """
    R, t = decompose_essential(E)[0]  # any of the four gives the same E up to sign
    for _ in range(rounds):
        distances = essential_distances(E, p1[inliers], p2[inliers], K)
        R, t = refine_relative_pose(R, t, p1[inliers], p2[inliers], K, loss="cauchy",
                                    scale_px=loss_scale_px(distances, threshold_px))
        E_new = essential_from_pose(R, t)
        threshold = inlier_threshold_px(distances, threshold_px)
        new_inliers = essential_distances(E_new, p1, p2, K) <= threshold
        if new_inliers.sum() < 6:
            break
        E = E_new
        if np.array_equal(new_inliers, inliers):
            break
        inliers = new_inliers
    return E, inliers
