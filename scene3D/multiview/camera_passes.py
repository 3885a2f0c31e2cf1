"""Photos of several cameras: the passes that reconstruct the views again with each
camera's focal length and lens the largest model calls for (:mod:`scene3D.multiview.cameras`),
as :mod:`scene3D.multiview.lens` does for one camera's lens.

A pass maps every camera's photographed keypoints with the cameras the previous model
implies, into the reference camera's pixels, and is kept when it registers no fewer
views; the passes stop when no image corner moves by more than
``SfMSettings.lens_tolerance_px``, when a camera's lens would fold over inside its
images, or after ``SfMSettings.max_lens_passes``.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Callable, Sequence
from dataclasses import dataclass

import numpy as np

from ..engines.timing import StageTimer
from ..errors import ReconstructionError
from ..geometry.conventions import FloatArray
from ..geometry.lens import folds_within
from .cameras import (
    CameraPass,
    corner_change_px,
    implied_coefficients,
    model_cameras,
    reference_camera,
    reference_features,
    refine_cameras,
)
from .settings import SfMSettings
from .sfm_model import FocalEstimate, SfMModel
from .view_data import ViewFeatures

#: What one reconstruction gives: the models, the reasons for the views left out, and the
#: pairs matched, and the pairs verified as (i, j, inliers) in the views' order.
Attempt = tuple[list[SfMModel], dict[int, str], int, list[tuple[int, int, int]]]


@dataclass(frozen=True)
class CameraViews:
    """The views of photos of several cameras, in the order the mapper works in.

    Attributes
    ----------
    view_camera : (V,) int ndarray
        The camera of each view.
    keypoints : list of (N_v, 2) float64
        Each view's keypoints as photographed (working pixels of its camera).
    sizes : list of (N_v,) float64 or None
        Their sizes (px), as photographed.
    prior_focal_px : (C,) float64
        Each camera's focal-length prior at its working size.
    prior_sigma_log : sequence of float
        Its standard deviation in ``log f``.
    image_sizes : sequence of (int, int)
        Each camera's working (width, height).
    """

    view_camera: np.ndarray
    keypoints: Sequence[FloatArray]
    sizes: Sequence[FloatArray | None]
    prior_focal_px: FloatArray
    prior_sigma_log: Sequence[float]
    image_sizes: Sequence[tuple[int, int]]


def camera_passes(
    attempt: Attempt,
    reconstruct: Callable[[FloatArray, list[ViewFeatures], FocalEstimate | None, np.ndarray],
                          Attempt],
    features: list[ViewFeatures],
    views: CameraViews,
    used: CameraPass,
    K_work: FloatArray,
    lens_passes: int,
    num_radial: int,
    settings: SfMSettings,
    say: Callable[[str], None],
    timer: StageTimer,
) -> tuple[Attempt, CameraPass, FloatArray, int]:
    """Reconstruct the views again with the cameras the largest model calls for, while it
    moves them (see the module docstring).

    Parameters
    ----------
    attempt : (models, reasons, matched, verified edges)
        The last reconstruction, made with the cameras ``used``.
    reconstruct : callable
        ``reconstruct(K_work, features, start_from, known_cameras) -> Attempt``: the views
        reconstructed from ``features`` (in the reference pixels ``K_work``), the focal
        length starting from ``start_from`` (None: self-calibrated), the cameras
        ``known_cameras`` (``(C,) bool``) not searched for; raises
        :class:`~scene3D.errors.ReconstructionError` when no model comes out.
    features : list of ViewFeatures
        The views' features that ``attempt`` was made from.
    views : CameraViews
        The views' cameras, photographed keypoints and priors.
    used : CameraPass
        The cameras ``features`` were mapped with.
    K_work : (3, 3) ndarray
        The reference pixels' intrinsics.
    lens_passes : int
        Passes made so far (at most ``settings.max_lens_passes`` in all).
    num_radial : int
        Radial coefficients of the camera model (0: pinhole).
    settings : SfMSettings
    say : callable
        Called with one line of text per pass.
    timer : StageTimer
        Its stage ``"lens"`` times the fits of the cameras.

    Returns
    -------
    attempt : (models, reasons, matched, verified edges)
        The last reconstruction kept.
    used : CameraPass
        The cameras it was made with.
    K_work : (3, 3) ndarray
        Its reference pixels' intrinsics.
    lens_passes : int
        Passes made in all.
    """
    s = settings
    models = attempt[0]
    num_cameras = len(views.prior_focal_px)
    while lens_passes < s.max_lens_passes:
        with timer.stage("lens"):
            fit = refine_cameras(models[0], views.view_camera, used, K_work, views.prior_focal_px,
                                 views.prior_sigma_log)
            implied = model_cameras(models[0], used, K_work)
            k_implied = implied_coefficients(used, implied)
            seen = np.zeros(num_cameras, dtype=bool)
            seen[views.view_camera[models[0].registered]] = True
            moved = max(corner_change_px(implied[c], k_implied[c], fit.K[c],
                                         fit.k[c], views.image_sizes[c])
                        for c in np.flatnonzero(seen))
        if moved <= s.lens_tolerance_px:
            break
        folding = [c for c in np.flatnonzero(seen)
                   if folds_within(fit.K[c], fit.k[c], views.image_sizes[c])]
        if folding:
            say(f"the lens the model calls for folds over inside the images of camera "
                f"{folding[0] + 1}: keeping the last cameras")
            break
        say("cameras: " + "; ".join(
            f"{c + 1} f {fit.K[c, 0, 0]:.1f} px" + (f", k1 {fit.k[c, 0]:+.3f}" if num_radial
                                                   else "")
            for c in np.flatnonzero(seen))
            + f" (the image corners move up to {moved:.1f} px): reconstructing with them")
        kept = features, used, K_work
        used = CameraPass(np.where(seen[:, None, None], fit.K, used.K),
                          np.where(seen[:, None], fit.k, used.k), used.known | seen)
        K_work = used.K[reference_camera(views.view_camera)]
        features = reference_features(features, views.keypoints, views.sizes,
                                      views.view_camera, used.K, used.k, K_work)
        start_from = None if models[0].focal is None else dataclasses.replace(
            models[0].focal, start_focal_px=float(K_work[0, 0]))
        try:
            new = reconstruct(K_work, features, start_from, used.known)
        except ReconstructionError as exc:
            new, why = None, str(exc)
        else:
            why = "it registers fewer views"
            if new[0][0].registered.sum() >= models[0].registered.sum():
                attempt, models = new, new[0]
                lens_passes += 1
                continue
        say(f"no better model with these cameras ({why}): keeping the last")
        features, used, K_work = kept
        break
    return attempt, used, K_work, lens_passes
