"""The result of :func:`scene3D.multiview.pipeline.reconstruct_views` in the input order:
a model computed on the views in their canonical order (by content) put back in the input
order (:func:`to_input_order`), and the result of photos of several cameras
(:func:`cameras_result`).
"""

from __future__ import annotations

import dataclasses
from collections.abc import Sequence

import numpy as np

from ..geometry.intrinsics_prior import FocalPrior
from ..optim.bundle import Observations, reprojection_residuals
from .cameras import (
    CameraPass,
    camera_pixels,
    implied_coefficients,
    model_cameras,
    reference_camera,
)
from .models import CameraIntrinsics, MultiViewReconstruction
from .sfm_model import SfMModel


def to_input_order(model: SfMModel, order: np.ndarray) -> SfMModel:
    """A model computed on views ``order`` (canonical position -> input index), with every
    per-view array and view index put back in the input order.

    Parameters
    ----------
    model : SfMModel
        Computed on the views in the canonical order.
    order : (V,) int ndarray
        The input index of each canonical position.

    Returns
    -------
    SfMModel
    """
    def per_view(a: np.ndarray) -> np.ndarray:
        out = np.empty_like(a)
        out[order] = a
        return out

    obs = model.observations
    check = model.check
    focal = model.focal
    if focal is not None and focal.start_pair is not None:
        focal = dataclasses.replace(focal, start_pair=(int(order[focal.start_pair[0]]),
                                                       int(order[focal.start_pair[1]])))
    return dataclasses.replace(
        model, registered=per_view(model.registered), R=per_view(model.R), t=per_view(model.t),
        observations=Observations(order[obs.view], obs.point, obs.xy),
        check=dataclasses.replace(
            check, inconsistent_pairs=tuple((int(order[i]), int(order[j]), r)
                                            for i, j, r in check.inconsistent_pairs),
            suspect_views=tuple(sorted(int(order[v]) for v in check.suspect_views))),
        focal=focal)


def cameras_result(models: list[SfMModel], used: CameraPass, K_reference: np.ndarray,
                    canonical_camera: np.ndarray, order: np.ndarray, reasons: dict[int, str],
                    common: dict, priors: Sequence[FocalPrior], view_camera: np.ndarray,
                    camera_sizes: Sequence[tuple[int, int]]) -> MultiViewReconstruction:
    """The result of photos of several cameras: every model's observations in each
    view's own working pixels and its cameras (``SfMModel.camera_K``), the largest
    model's cameras as the result's, all in the input order.

    Parameters
    ----------
    models : list of SfMModel
        The models, largest first, in the canonical order and the reference pixels.
    used : CameraPass
        The cameras their keypoints were mapped with.
    K_reference : (3, 3) ndarray
        The reference pixels' intrinsics.
    canonical_camera : (V,) int ndarray
        The camera of each view, in the canonical order.
    order : (V,) int ndarray
        The input index of each canonical position.
    reasons : dict of int to str
        Why each view left out (canonical index) is.
    common : dict
        The other fields of the result (names, pairs, timings, ...).
    priors : sequence of FocalPrior
        One per camera.
    view_camera : (V,) int ndarray
        The camera of each view, in the input order.
    camera_sizes : sequence of (int, int)
        Each camera's working (width, height).

    Returns
    -------
    MultiViewReconstruction
    """
    r = reference_camera(canonical_camera)
    out = []
    for model in models:
        K_model = model.K if model.K is not None else K_reference
        K_cameras = model_cameras(model, used, K_reference)
        obs = camera_pixels(model, canonical_camera, K_model, K_cameras)
        residuals = np.concatenate([reprojection_residuals(
            model.R, model.t, model.points3d, Observations(obs.view[rows], obs.point[rows],
                                                           obs.xy[rows]), K_cameras[c])
            for c in range(len(priors))
            for rows in [canonical_camera[obs.view] == c]])
        rmse = float(np.sqrt(np.mean(residuals**2))) if len(residuals) else float("nan")
        out.append(dataclasses.replace(model, observations=obs, reprojection_rmse_px=rmse,
                                       K=K_cameras[r], camera_K=K_cameras))
    main = out[0]
    k = implied_coefficients(used, main.camera_K)
    seen = np.zeros(len(priors), dtype=bool)
    seen[canonical_camera[main.registered]] = True
    dists = [np.concatenate([k[c], np.zeros(4 - k.shape[1])]) if np.any(k[c]) else np.zeros(0)
             for c in range(len(priors))]
    # A camera the largest model does not see keeps what its keypoints were mapped with
    # (a focal search that found no pose confirms nothing).
    K_out = np.where(seen[:, None, None], main.camera_K, used.K)
    dists = [d if seen[c] else (np.concatenate([used.k[c], np.zeros(4 - used.k.shape[1])])
                                if np.any(used.k[c]) else np.zeros(0))
             for c, d in enumerate(dists)]
    cameras = tuple(CameraIntrinsics(K_out[c], dists[c], tuple(camera_sizes[c]),
                                     tuple(prior.image_size), prior.camera_name,
                                     prior.description, bool(seen[c]))
                    for c, prior in enumerate(priors))
    names = common["names"]
    return MultiViewReconstruction(
        K=main.camera_K[r].copy(), image_size=tuple(camera_sizes[r]),
        models=tuple(to_input_order(m, order) for m in out),
        unregistered_reasons={names[order[v]]: why for v, why in sorted(
            reasons.items(), key=lambda item: order[item[0]])},
        calibration_source=main.focal.source if main.focal is not None else "prior",
        prior_description=priors[r].description, photo_size=tuple(priors[r].image_size),
        dist=dists[r], view_camera=np.asarray(view_camera, dtype=int), cameras=cameras,
        **common)
