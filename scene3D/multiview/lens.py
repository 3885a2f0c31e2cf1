"""Lens distortion for photos without a calibration file: undistorted keypoints, refined.

Without a calibration the camera model (:mod:`scene3D.geometry.lens`) is ``f`` and
radial coefficients about the image centre. Its distortion is found from a model and
applied to the keypoints, so that the pair verification, the focal and consistency
checks and the registrations all work in the undistorted geometry of the current
estimate:

1. The views are reconstructed with the keypoints as they are (the coefficients 0). When
   no pair gives a start so, or the consistency check leaves the first model no views,
   the keypoints are undistorted with a first guess from the pairs with most matches
   (:func:`pair_lens_guess`) and the views reconstructed again.
2. The largest model is adjusted on the photographed keypoints with the focal length and
   the coefficients free (:func:`scene3D.optim.bundle_radial.bundle_adjust_radial`), starting from
   the lens its keypoints were undistorted with (exact: pixels undistorted with one
   focal length and taken by a pinhole camera of another are an exact radial camera,
   :func:`scene3D.geometry.lens.rescaled_coefficients`).
3. When that lens moves an image corner more than ``SfMSettings.lens_tolerance_px``
   from where the current undistortion puts it, the keypoints are undistorted with it
   and the views reconstructed again (the model made with the last lens keeps only the
   observations that fit it, which biases the next estimate towards that lens, so the
   estimate moves over several passes), at most ``SfMSettings.max_lens_passes`` times; a
   pass that registers fewer views is not kept.

A lens that hardly distorts leaves the keypoints as they are and the models as a pinhole
camera would give them (``SfMSettings.min_lens_shift``).
"""

from __future__ import annotations

import dataclasses
from collections.abc import Sequence

import cv2
import numpy as np

from ..geometry.conventions import FloatArray
from ..geometry.lens import distort_pixels, rescaled_coefficients, undistort_pixels
from ..optim.bundle import Observations
from ..optim.bundle_radial import RadialAdjustment, bundle_adjust_radial
from ..twoview.distortion_fit import fit_radial_distortion
from .focal import FocalSettings
from .sfm_model import SfMModel
from .view_data import PairMatches, ViewFeatures

#: The coefficients' prior standard deviation: weak, it holds them only where a model's
#: views do not determine them (COLMAP's SIMPLE_RADIAL starts at 0 with none).
K_PRIOR_SIGMA = 0.5


def refine_lens(model: SfMModel, K_model: FloatArray, lens: FloatArray,
                K_lens: FloatArray, focal: FocalSettings) -> RadialAdjustment:
    """The focal length and radial coefficients a model calls for, on the photographed
    keypoints.

    Parameters
    ----------
    model : SfMModel
        Its observations are keypoints undistorted with ``(K_lens, lens)``.
    K_model : (3, 3)
        The intrinsics it was adjusted with.
    lens : (m,)
        The coefficients the keypoints were undistorted with, about ``K_lens``.
    K_lens : (3, 3)
    focal : FocalSettings
        The focal length's prior.

    Returns
    -------
    RadialAdjustment
        About the image centre and the refined focal length; ``k`` has ``m`` entries.
    """
    obs = model.observations
    raw = Observations(obs.view, obs.point, distort_pixels(obs.xy, K_lens, lens), obs.sigma)
    # The model's world is its initial pair's first camera, [I | 0]: it stays.
    views = np.flatnonzero(model.registered)
    reference = int(views[np.argmin(np.linalg.norm(model.t[views], axis=1))])
    start = rescaled_coefficients(lens, float(K_lens[0, 0]), float(K_model[0, 0]))
    return bundle_adjust_radial(model.R, model.t, model.points3d, raw, K_model, start,
                                reference, focal.prior_focal_px, focal.prior_sigma_log,
                                K_PRIOR_SIGMA)


def undistorted_features(features: Sequence[ViewFeatures], raw_keypoints: Sequence[FloatArray],
                         K_lens: FloatArray, lens: FloatArray) -> list[ViewFeatures]:
    """The views' features with their photographed keypoints undistorted by ``(K_lens,
    lens)`` (everything else as it is).

    Parameters
    ----------
    features : sequence of ViewFeatures
        The views' features.
    raw_keypoints : sequence of (N_v, 2) array_like
        Each view's keypoints as photographed (pixels, OpenCV convention).
    K_lens : (3, 3) array_like
        Intrinsics the coefficients refer to.
    lens : (m,) array_like
        Radial coefficients (:mod:`scene3D.geometry.lens`).

    Returns
    -------
    list of ViewFeatures
    """
    return [dataclasses.replace(f, keypoints=undistort_pixels(raw, K_lens, lens))
            for f, raw in zip(features, raw_keypoints)]



def pair_lens_guess(pairs: Sequence[PairMatches], features: Sequence[ViewFeatures],
                    K: FloatArray, candidates: int = 3) -> float | None:
    """A first ``k1`` for photos that give no start as they are: the median of the
    one-coefficient lens (:func:`scene3D.twoview.distortion_fit.fit_radial_distortion`,
    the division model, ``k`` about ``k1`` for the distortions of photos) that best
    explains each of the ``candidates`` pairs with most verified matches, under ``K``.

    A lens that bends the matches makes every pair call for another focal length than
    the one it has, so no pair may look trustworthy (the two-view checks work in the
    pinhole geometry); undistorted with this guess, the start's self-calibration and
    checks see the geometry again, and the models' adjustments refine the lens
    (:func:`refine_lens`).

    Parameters
    ----------
    pairs : sequence of PairMatches
        Verified pairs.
    features : sequence of ViewFeatures
        The views' features (keypoints as photographed).
    K : (3, 3) array_like
        Intrinsics (the prior's focal length).
    candidates : int, default 3
        Number of pairs with most inliers that are fitted.


    Returns
    -------
    float or None
        None when no pair determines a coefficient.
    """
    guesses = []
    for p in sorted(pairs, key=lambda p: -p.num_inliers)[:candidates]:
        pts1 = features[p.i].keypoints[p.idx_i]
        pts2 = features[p.j].keypoints[p.idx_j]
        E, _ = cv2.findEssentialMat(pts1, pts2, K, method=cv2.LMEDS)
        if E is None or E.shape != (3, 3):
            continue
        _, R, t, _ = cv2.recoverPose(E, pts1, pts2, K)
        fit = fit_radial_distortion(R, t.ravel(), pts1, pts2, K)
        if np.isfinite(fit.k) and np.isfinite(fit.sigma):
            guesses.append(fit.k)
    return float(np.median(guesses)) if guesses else None
