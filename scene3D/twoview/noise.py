"""The keypoint noise behind Sampson distances, and the loss scales and thresholds it sets.

The robust essential matrix (:mod:`scene3D.twoview.essential_fit`) and the two-view
pipeline refine under a Cauchy loss whose scale follows the noise of the images at hand
(:func:`loss_scale_px`), re-select inliers at a threshold the noise may raise
(:func:`inlier_threshold_px`), and compare restarts at the threshold the noise calls for
(:func:`comparison_threshold_px`). Distances are Sampson distances in pixels
(:func:`scene3D.geometry.epipolar.essential_distances`).
"""

from __future__ import annotations

import numpy as np

from ..geometry.conventions import FloatArray, median

#: Scale of the local optimisation's Cauchy loss in standard deviations of the noise:
#: 2.385 sigma keeps 95 % of least squares' efficiency under Gaussian noise (Holland
#: and Welsch, 1977) and still discounts the heavy tail of real matches.
CAUCHY_SCALE_OF_SIGMA = 2.385

#: Inlier threshold in standard deviations of the noise, when the noise is larger than
#: the given threshold assumes, and how far it may be raised (times the given one).
THRESHOLD_OF_SIGMA = 3.0
MAX_THRESHOLD_GROWTH = 2.0

#: The restarts of :func:`scene3D.twoview.essential_fit.fit_essential` first probe the
#: keypoint noise with a robust estimation at this fraction of the inlier threshold, and
#: compare their optima at :data:`THRESHOLD_OF_SIGMA` times that noise, never below this
#: fraction of the threshold (:func:`comparison_threshold_px`). The default 1 px threshold
#: leaves room for noise of a third of a pixel, more than SIFT keypoints show on the
#: Strecha scenes (docs/benchmarks.md#castle-p19-repeated-windows).
NOISE_PROBE_OF_THRESHOLD = 0.125


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
    """Threshold (pixels) at which the restarts of the robust essential matrix compare
    their optima (:func:`scene3D.twoview.essential_fit.fit_essential`).

    ``distances`` ``(N,)`` are the Sampson distances of all correspondences to a
    model fitted within the noise (the noise probe of
    :func:`scene3D.twoview.essential_fit.fit_essential`); those
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
