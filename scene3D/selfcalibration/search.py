"""Finding the focal length: the profile of the robust cost over focal lengths, the
iteration from its basins, and the combination with a prior (see :mod:`scene3D.selfcalibration`)."""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from ..geometry.camera import with_focal
from ..geometry.conventions import FloatArray
from ..geometry.epipolar import essential_distances
from ..twoview import TwoViewGeometry, TwoViewSettings, reconstruct_from_matches
from ..twoview.essential_fit import essential_cost, fit_essential, noise_sigma_px


@dataclass(frozen=True)
class FocalProfile:
    """The robust cost of the best pose at each of several focal lengths.

    Attributes
    ----------
    focal_px : (n,) float64
        The focal lengths tried, increasing.
    cost : (n,) float64
        :func:`scene3D.twoview.essential_fit.essential_cost` of each one's robust fit over all
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


def focal_profile(pts1: FloatArray, pts2: FloatArray, K: FloatArray, factors: FloatArray,
                  threshold_px: float, min_threshold_px: float,
                  min_inliers: int = 15) -> FocalProfile:
    """The robust cost of the best pose at focal lengths ``K[0, 0] * factors``.

    At each focal length one robust estimation of E with local optimisation
    (:func:`scene3D.twoview.essential_fit.fit_essential`, one start: the profile only has to
    find the basins). Each fit is scored over all matches ``pts1, pts2`` ``(N, 2)``
    by :func:`scene3D.twoview.essential_fit.essential_cost` at one threshold for all: three
    times the smallest robust noise sigma of their inliers (the fit nearest the
    truth has the least spread), at least ``min_threshold_px`` and at most
    ``threshold_px``. Pixels, and so the costs, are comparable across focal lengths.

    Parameters
    ----------
    pts1, pts2 : (N, 2) array_like
        Matched pixels in images 1 and 2.
    K : (3, 3) array_like
        Intrinsics whose focal length is scaled.
    factors : (F,) array_like
        Focal-length factors.
    threshold_px : float
        Inlier threshold (px).
    min_threshold_px : float
        Smallest scoring threshold (px).
    min_inliers : int, default 15
        Fewest inliers for a fit to measure the noise.

    Returns
    -------
    FocalProfile
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

    Parameters
    ----------
    pts1, pts2 : (N, 2) array_like
        Matched pixels in images 1 and 2.
    K : (3, 3) array_like
        Starting intrinsics.
    settings : TwoViewSettings
        The two-view settings.
    max_iterations : int
        Most rounds.
    tolerance_log : float
        Convergence tolerance on ``log f``.

    Returns
    -------
    geometry : TwoViewGeometry
    rounds : int
    converged : bool


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


def combine_log_normal(focal1: float, sigma1: float, focal2: float,
                       sigma2: float) -> tuple[float, float]:
    """Inverse-variance combination of two focal lengths known to ``sigma`` in ``log f``.

    Returns ``(focal, sigma_log)``. An infinite sigma contributes nothing.

    Parameters
    ----------
    focal1, focal2 : float
        Focal lengths (px).
    sigma1, sigma2 : float
        Their standard deviations in ``log f``.
    """
    w1 = 0.0 if not math.isfinite(sigma1) else 1.0 / sigma1**2
    w2 = 0.0 if not math.isfinite(sigma2) else 1.0 / sigma2**2
    if w1 + w2 == 0.0:
        return focal1, math.inf
    log_f = (w1 * math.log(focal1) + w2 * math.log(focal2)) / (w1 + w2)
    return math.exp(log_f), 1.0 / math.sqrt(w1 + w2)
