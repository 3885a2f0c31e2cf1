"""Comparing fits of the essential matrix: a robust cost over all matches, and angles.

The restarts of :func:`scene3D.twoview.essential_fit.fit_essential` end at optima refined
on different inliers; :func:`essential_cost` ranks them on all the correspondences,
:func:`essential_angle_deg` says how far apart two lie, and :func:`rival_spread_deg` how far
from the best lie those that fit about as well. Conventions: ``x2n^T E x1n = 0`` for
normalised coordinates, ``E = [t]x R`` (:mod:`scene3D.geometry`).
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike

from ..geometry.conventions import FloatArray, pose_angle_deg
from ..geometry.epipolar import essential_distances
from ..geometry.pose import decompose_essential, nearest_decomposition
from ..optim.least_squares import robust_loss

#: Scale of the Cauchy loss of the MSAC-style cost that compares models, as a fraction
#: of the inlier threshold (the threshold taken as about three standard deviations of
#: keypoint noise): one fixed scale, so that models fitted to different inliers compare.
LOSS_SCALE_OF_THRESHOLD = 1.0 / 3.0

#: Refined starts' optima whose robust cost (:func:`essential_cost`, a Cauchy negative
#: log-likelihood up to a constant) exceeds the best by more than this fit the matches
#: measurably worse: half the 99 % quantile of chi-squared with 5 degrees of freedom
#: (those of a relative pose), the likelihood-ratio test. Only the others count in
#: :attr:`scene3D.twoview.essential_fit.EssentialFit.spread_deg`.
COMPARABLE_COST = 0.5 * 15.09


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


def same_essential(E1: FloatArray, E2: FloatArray, tolerance: float = 1e-4) -> bool:
    """True when two unit-norm essential matrices agree up to sign (the same local optimum).

    Parameters
    ----------
    E1, E2 : (3, 3) ndarray
        Essential matrices of unit Frobenius norm.
    tolerance : float, default 1e-4
        Largest difference of an entry.

    Returns
    -------
    bool
    """
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
