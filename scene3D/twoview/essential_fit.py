"""The robust essential matrix: restarts, local optimisation and noise-adaptive thresholds.

:func:`fit_essential` runs a robust USAC estimation (5-point solver) and a local
optimisation of the pose on its inliers (:func:`refine_essential`: the Sampson
refinement of :func:`scene3D.optim.refinement.refine_relative_pose` under a Cauchy loss
whose scale follows the keypoints' noise), restarted until the best fit repeats, the
starts' optima compared by a robust cost (:func:`essential_cost`) at the noise of the
keypoints. The relations it builds on (Sampson distances, ``E`` from a pose, ``F``
from ``E``) and the robust ``F`` and ``H`` are in :mod:`scene3D.geometry.epipolar`; the
robust cost and the angles that compare optima in :mod:`scene3D.twoview.essential_compare`,
the noise-adaptive scales and thresholds in :mod:`scene3D.twoview.noise` (both re-exported
here, their old home).

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
from ..geometry.conventions import FloatArray, distinct_correspondences
from ..geometry.epipolar import (
    ROBUST_METHOD,
    check_correspondences,
    essential_distances,
    essential_from_pose,
    inlier_mask,
)
from ..geometry.pose import decompose_essential, nearest_decomposition
from ..optim.refinement import refine_relative_pose, relative_pose_covariance
from ..optim.uncertainty import CHI2_99_POSE, pose_difference_chi2
from .essential_compare import (  # noqa: F401  (re-exported: their old home)
    COMPARABLE_COST,
    LOSS_SCALE_OF_THRESHOLD,
    essential_angle_deg,
    essential_cost,
    essential_costs,
    rival_spread_deg,
    same_essential,
)
from .noise import (  # noqa: F401  (re-exported: their old home)
    CAUCHY_SCALE_OF_SIGMA,
    MAX_THRESHOLD_GROWTH,
    NOISE_PROBE_OF_THRESHOLD,
    THRESHOLD_OF_SIGMA,
    comparison_threshold_px,
    inlier_threshold_px,
    loss_scale_px,
    noise_sigma_px,
)

#: Robust estimator of the restarts of :func:`fit_essential` when they run below the
#: given threshold: USAC with MSAC scoring and local optimisation (LO-RANSAC). At a
#: threshold near the noise it keeps the tightest consensus; MAGSAC++ marginalises over
#: noise levels up to the threshold and, on repeated structure, returns the model that
#: also fits the mismatches more loosely. At the given threshold (matches as noisy as it
#: allows) the restarts use :data:`scene3D.geometry.epipolar.ROBUST_METHOD`, which suits noise of
#: that size better.
RESTART_METHOD = cv2.USAC_DEFAULT



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
    (docs/benchmarks.md#castle-p19-repeated-windows). Within the
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
    another pose fits (mismatched windows half a pixel to a pixel off their epipolar
    lines; docs/benchmarks.md#the-wider-refinement-against-the-fit-within-the-noise), and
    the optimum within the
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
        its covariance, which fewer residuals leave too uncertain (below 50 it fired
        where the wider refinement was the nearer to the truth:
        docs/benchmarks.md#the-wider-refinement-against-the-fit-within-the-noise;
        ``TwoViewSettings.trusted_inliers`` is the same floor).

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
        confirmed = sum(same_essential(E_, best_E) for _, E_, _ in fits) >= 2
        if confirmed:
            break
    if not fits:
        return EssentialFit(np.full((3, 3), np.nan), np.zeros(n, dtype=bool), max_starts,
                            refinement_s, comparison_threshold_px=tau, fitted_threshold_px=tau)
    best_cost, E, inliers = min(fits, key=lambda fit: fit[0])
    spread = rival_spread_deg([(cost, E_other) for cost, E_other, _ in fits])
    rivals = tuple(E_other for cost, E_other, _ in fits
                   if cost <= best_cost + COMPARABLE_COST and not same_essential(E_other, E))
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
