"""The summary of a many-view reconstruction as plain data, and its errors against ground truth.

:meth:`scene3D.multiview.MultiViewReconstruction.to_dict` gives the summary that
``scene3d reconstruct-views`` writes as ``reconstruction.json`` (without the command's
``timings_s`` total and its list of files): one entry per model (:func:`model_summary`),
its consistency check (:func:`check_summary`), its self-calibration
(:func:`focal_summary`) and, given the cameras of a Strecha scene, its camera errors
(:func:`ground_truth_errors`). Arrays stay numpy arrays
(:func:`scene3D.io.export.write_json` writes them).

Frames as in :mod:`scene3D.multiview.models`: each model's world is the camera frame of
the first view of its initial pair, ``x_cam = R X + t``, arbitrary scale.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from ..evaluation.poses import camera_set_error
from ..features.matching import resolve_feature_mode
from ..io.model_folder import model_folder_name

if TYPE_CHECKING:
    from ..io.datasets import StrechaCamera
    from .models import MultiViewReconstruction, SfMModel

#: What to ask when the views refute the calibration's focal length.
CALIBRATION_QUESTION = ("is the calibration for this camera, lens and zoom, with the lens's "
                        "distortion?")

#: The summary's statement of the frames.
CONVENTIONS = ("each model: world = camera frame of the first view of its initial pair; "
               "x_cam = R @ X + t; arbitrary scale")


def check_summary(model: SfMModel, names: list[str]) -> dict:
    """A model's consistency check (:class:`scene3D.multiview.models.ModelCheck`) as data.

    Parameters
    ----------
    model : SfMModel
    names : list of str
        The reconstruction's view names (``MultiViewReconstruction.names``).

    Returns
    -------
    dict
        ``status`` (``"ok"`` or ``"failed"``), ``pairs_checked``, ``inconsistent_pairs``
        (views and median epipolar distance in pixels), ``suspect_views`` and, when the
        views determine it, ``focal_scale`` and its ``focal_scale_sigma``.
    """
    check = model.check
    return {
        "status": "ok" if check.ok else "failed",
        "pairs_checked": check.pairs_checked,
        "inconsistent_pairs": [{"views": [names[i], names[j]], "median_epipolar_px": r}
                               for i, j, r in check.inconsistent_pairs],
        "suspect_views": [names[v] for v in check.suspect_views],
        **({"focal_scale": check.focal_scale,
            "focal_scale_sigma": check.focal_scale * check.focal_scale_sigma_log}
           if np.isfinite(check.focal_scale_sigma_log) else {}),
    }


def focal_summary(recon: MultiViewReconstruction, model: SfMModel,
                  camera: str | None = None) -> dict:
    """A model's self-calibration (photos without a calibration file) as data.

    Parameters
    ----------
    recon : MultiViewReconstruction
    model : SfMModel
        One of ``recon.models``.
    camera : str, optional
        The photos' camera, as their EXIF names it
        (:attr:`scene3D.geometry.intrinsics_prior.FocalPrior.camera_name`).

    Returns
    -------
    dict
        Empty with a calibration file; else the prior, the start, the photos' focal
        length (pixels of the working images) and the standard deviations of its log.
    """
    f = model.focal
    if f is None:
        return {}
    return {
        "start": recon.prior_description, "camera": camera,
        "prior_focal_px": f.prior_focal_px, "prior_sigma_log": f.prior_sigma_log,
        "start_focal_px": f.start_focal_px,
        "start_pair": None if f.start_pair is None else [recon.names[v] for v in f.start_pair],
        "photos_focal_px": f.data_focal_px, "photos_sigma_log": f.data_sigma_log,
        "adjustment_sigma_log": f.adjustment_sigma_log,
        "principal_point_sigma_log": f.principal_point_sigma_log,
        "jackknife_sigma_log": f.jackknife_sigma_log,
        "determined": f.determined, "trusted": f.trusted, "warnings": list(f.warnings),
    }


def ground_truth_errors(cameras: list[StrechaCamera], names: list[str], model: SfMModel,
                        K: np.ndarray | None = None,
                        image_size: tuple[int, int] | None = None) -> dict:
    """A model's camera errors against Strecha ground truth, after a similarity alignment.

    Parameters
    ----------
    cameras : list of StrechaCamera
        One per view, in the input order (:func:`scene3D.io.datasets.read_strecha_cameras`).
    names : list of str
        The view names.
    model : SfMModel
    K : (3, 3) array, optional
        The model's self-calibrated intrinsics; with ``image_size`` its focal error
        against the camera files' (``sqrt(fx fy)``, scaled to the working width) is given.
    image_size : (int, int), optional
        (width, height) of the working images.

    Returns
    -------
    dict
        ``views`` (the registered ones), per view ``center_error_fraction_of_extent``
        and ``rotation_error_deg`` (arrays), their maxima and medians, and with ``K``
        ``true_focal_px`` and ``focal_error_fraction``.
    """
    reg = [i for i in range(len(names)) if model.registered[i]]
    truth = [cameras[i] for i in reg]
    err = camera_set_error(model.R[reg], model.centers[reg], np.array([c.R for c in truth]),
                           np.array([c.center for c in truth]))
    focal = {}
    if K is not None and image_size is not None:
        c = truth[0]
        true_focal = float(np.sqrt(c.K[0, 0] * c.K[1, 1]) * image_size[0] / c.image_size[0])
        focal = {"true_focal_px": true_focal, "focal_error_fraction": K[0, 0] / true_focal - 1}
    return {**focal,
        "views": [names[i] for i in reg],
        "center_error_fraction_of_extent": err.center_errors,
        "rotation_error_deg": err.rotation_errors_deg,
        "max_center_error_fraction": float(err.center_errors.max()),
        "median_center_error_fraction": float(np.median(err.center_errors)),
        "max_rotation_error_deg": float(err.rotation_errors_deg.max()),
        "median_rotation_error_deg": float(np.median(err.rotation_errors_deg)),
    }


def refit_warnings(recon: MultiViewReconstruction) -> list[str]:
    """What to say when the views refuted the calibration's focal length (else nothing).

    Parameters
    ----------
    recon : MultiViewReconstruction

    Returns
    -------
    list of str
        One sentence with the factors (:attr:`MultiViewReconstruction.focal_refits`), or
        none when the calibration held.
    """
    if not recon.focal_refits:
        return []
    steps = (" (" + ", then ".join(f"{f:.3f}" for f in recon.focal_refits) + ")"
             if len(recon.focal_refits) > 1 else "")
    return [f"the views refuted the calibration's focal length: they were reconstructed "
            f"with the one they called for, {recon.focal_refit_scale:.3f} times it"
            f"{steps}, K in reconstruction.json; {CALIBRATION_QUESTION}"]


def model_summary(recon: MultiViewReconstruction, m: int, camera: str | None = None,
                  cameras: list[StrechaCamera] | None = None) -> dict:
    """Model ``m`` of ``recon`` as data: the entry of the summary's ``models``.

    Parameters
    ----------
    recon : MultiViewReconstruction
    m : int
        Index into ``recon.models`` (0: the largest).
    camera : str, optional
        The photos' camera (:func:`focal_summary`).
    cameras : list of StrechaCamera, optional
        Ground truth, one per view (:func:`ground_truth_errors`).

    Returns
    -------
    dict
        ``folder`` (:func:`scene3D.io.model_folder.model_folder_name`), ``status`` (``"ok"``
        when :meth:`MultiViewReconstruction.model_ok`), the views, counts, errors and check;
        with a self-calibration its ``K`` and focal length; with ``cameras`` ``ground_truth``.
    """
    names = list(recon.names)
    model = recon.models[m]
    entry = {
        "folder": model_folder_name(m),
        "status": "ok" if recon.model_ok(model) else "failed",
        "views": [names[i] for i in model.views], "registered": len(model.views),
        "points": len(model.points3d), "mean_track_length": model.mean_track_length,
        "reprojection_rmse_px": model.reprojection_rmse_px,
        "check": check_summary(model, names),
    }
    if model.focal is not None:
        entry["K"] = recon.model_K(model)
        entry["focal_px_sigma"] = model.focal.sigma_px
        entry["calibration_source"] = model.focal.source
        entry["self_calibration"] = focal_summary(recon, model, camera)
    if cameras is not None:
        entry["ground_truth"] = ground_truth_errors(
            cameras, names, model, recon.model_K(model) if model.focal is not None else None,
            recon.image_size)
    return entry


def reconstruction_summary(recon: MultiViewReconstruction, camera: str | None = None,
                           cameras: list[StrechaCamera] | None = None) -> dict:
    """The whole reconstruction as data (:meth:`MultiViewReconstruction.to_dict`).

    Parameters
    ----------
    recon : MultiViewReconstruction
    camera : str, optional
        The photos' camera, for a self-calibration (:func:`focal_summary`).
    cameras : list of StrechaCamera, optional
        Ground truth, one per view (:func:`ground_truth_errors`).

    Returns
    -------
    dict
        ``status`` (``"ok"`` when ``recon.ok``), the counts and errors of the largest
        model, ``models`` (:func:`model_summary`), the pairs, ``K``, the focal-length
        refits and ``warnings``, the self-calibration (None with a calibration file), the
        detector, the conventions, ``ground_truth`` of the largest model (with
        ``cameras``) and ``timings_s``.
    """
    models = [model_summary(recon, m, camera, cameras) for m in range(len(recon.models))]
    main = models[0]
    summary = {
        "status": "ok" if recon.ok else "failed",
        "views": len(recon.names), "registered": main["registered"],
        "unregistered": list(recon.unregistered),
        "unregistered_reasons": recon.unregistered_reasons,
        "models": models, "points": main["points"],
        "mean_track_length": recon.mean_track_length,
        "reprojection_rmse_px": recon.reprojection_rmse_px,
        "pair_selection": recon.pair_selection, "matched_pairs": recon.matched_pairs,
        "verified_pairs": recon.verified_pairs,
        "image_size": list(recon.image_size), "K": recon.K,
        "calibration_source": recon.calibration_source,
        "camera_model": recon.camera_model, "distortion": list(recon.dist),
        "focal_refits": list(recon.focal_refits),
        "warnings": refit_warnings(recon),
        "focal_px_sigma": recon.focal_px_sigma,
        "self_calibration": main.get("self_calibration", {}) if recon.self_calibrated
        else None,
        "feature": resolve_feature_mode(recon.feature), "feature_requested": recon.feature,
        "conventions": CONVENTIONS,
    }
    if "ground_truth" in main:
        summary["ground_truth"] = main["ground_truth"]
    summary["cameras"] = camera_summaries(recon)
    summary["timings_s"] = dict(recon.timings_s)
    return summary


def camera_summaries(recon: MultiViewReconstruction) -> list[dict]:
    """Each camera of the photos (:attr:`MultiViewReconstruction.camera_list`) as plain
    data: its views, the photos' and working sizes, ``K`` at the working size and the
    focal length at the photos', the distortion, where the focal length started,
    whether the largest model estimated it, and whether it is the reference camera (the
    result's ``K``, ``dist`` and ``image_size``: :mod:`scene3D.multiview.cameras`).

    Parameters
    ----------
    recon : MultiViewReconstruction

    Returns
    -------
    list of dict
    """
    out = []
    reference = recon.reference_camera
    for c, camera in enumerate(recon.camera_list):
        scale = camera.photo_size[0] / camera.image_size[0]
        out.append({
            "camera": c + 1, "name": camera.name,
            "views": [n for n, v in zip(recon.names, recon.camera_of_view) if v == c],
            "photo_size": list(camera.photo_size), "image_size": list(camera.image_size),
            "K": camera.K, "focal_px_photo": float(camera.K[0, 0] * scale),
            "distortion": list(camera.dist), "start": camera.prior_description,
            "estimated": camera.estimated, "reference": c == reference})
    return out
