"""What ``scene3d reconstruct-views`` prints of its result (the report shows the same
lines): the models, each camera's focal length and lens, the ground-truth errors."""

from __future__ import annotations

import numpy as np

from ..errors import plural
from ..geometry.lens import max_shift_px, radial_coefficients
from ..multiview import CameraIntrinsics, FocalEstimate, MultiViewReconstruction, SfMSettings
from .common import focal_sigma_text

__all__ = ["model_name", "result_lines"]


def model_name(m: int, folder: str) -> str:
    """'the largest model', 'model 1 (model-1/)'."""
    return "the largest model" if m == 0 else f"model {m} ({folder}/)"


def _focal_text(K: np.ndarray, focal: FocalEstimate) -> str:
    """'690.7 px +-1.1 px (0.16 %) (prior+refined)', '...; untrusted)'."""
    return (f"{K[0, 0]:.1f} px {focal_sigma_text(focal.focal_px, focal.sigma_px)} "
            f"({focal.source}" + ("" if focal.trusted else "; untrusted") + ")")


def _lens_line(recon: MultiViewReconstruction) -> str:
    """The lens a reconstruction without a calibration found (``camera_model``, ``dist``)."""
    if not np.any(recon.dist):
        return (f"lens ({recon.camera_model}): none applied (it would move the image "
                f"corners less than {100 * SfMSettings.min_lens_shift:.2f} % of the diagonal)")
    k = recon.dist[:radial_coefficients(recon.camera_model)]
    names = ", ".join(f"k{i + 1} {v:+.4f}" for i, v in enumerate(k))
    shift = max_shift_px(recon.K, k, recon.image_size)
    return (f"lens ({recon.camera_model}): {names}, moving the image corners {shift:.1f} px "
            f"at the working size (the keypoints undistorted with it, the views reconstructed "
            f"again {plural(recon.lens_passes, 'time')})")


def _camera_line(c: int, camera: CameraIntrinsics, recon: MultiViewReconstruction) -> str:
    """'camera 2 (Canon ..., 3 views, 2074x1382): focal length 2070.7 px, k1 -0.0016'."""
    views = int(np.sum(recon.camera_of_view == c))
    scale = camera.photo_size[0] / camera.image_size[0]
    name = f"{camera.name}, " if camera.name else ""
    if not camera.estimated:
        return (f"camera {c + 1} ({name}{plural(views, 'view')}, {camera.photo_size[0]}x"
                f"{camera.photo_size[1]}): in no view of the largest model, focal length "
                f"{camera.K[0, 0] * scale:.1f} px as it started ({camera.prior_description})")
    lens = ", ".join(f"k{i + 1} {v:+.4f}" for i, v in
                     enumerate(camera.dist[:radial_coefficients(recon.camera_model)]))
    return (f"camera {c + 1} ({name}{plural(views, 'view')}, {camera.photo_size[0]}x"
            f"{camera.photo_size[1]}): focal length {camera.K[0, 0] * scale:.1f} px at the "
            f"photos' size" + (f", {lens}" if lens else "")
            + f" (started from {camera.prior_description})")


def result_lines(names: list[str], recon: MultiViewReconstruction, models: list[dict]
                  ) -> list[str]:
    """What the command prints of its result (the report shows the same lines)."""
    main = models[0]
    numbers = (f"{main['points']} points, mean track length {recon.mean_track_length:.2f}, "
               f"reprojection RMSE {recon.reprojection_rmse_px:.3f} px")
    if len(models) == 1:
        lines = [f"{main['registered']} of {len(names)} views registered, {numbers}"]
    else:
        placed = sum(entry["registered"] for entry in models)
        lines = [f"{placed} of {len(names)} views registered in {len(models)} models; the "
                 f"largest, {main['registered']} views: {numbers}"]
    if recon.cameras:
        lines += [_camera_line(c, camera, recon) for c, camera in enumerate(recon.cameras)]
    elif recon.focal is not None:
        how = "refined by the photos" if recon.focal.determined else \
            "kept: the photos could not refine it"
        sigma = focal_sigma_text(recon.focal.focal_px, recon.focal.sigma_px)
        lines.append(f"focal length {recon.K[0, 0]:.1f} px {sigma} at the working size "
                     f"({recon.prior_description}; {how}"
                     + ("" if recon.focal.trusted else "; untrusted") + ")")
    if not recon.cameras and recon.focal is not None and recon.camera_model != "pinhole":
        lines.append(_lens_line(recon))
    if recon.focal_refits:
        lines.append(f"focal length {recon.K[0, 0]:.1f} px at the working size, "
                     f"{recon.focal_refit_scale:.3f} times the calibration's (the views "
                     "refuted it)")
    if len(models) > 1:
        lines.append(f"the largest model: {', '.join(main['views'])}")
    for m, (entry, model) in enumerate(zip(models[1:], recon.models[1:]), start=1):
        focal = ("" if model.focal is None else
                 f"; focal length {_focal_text(recon.model_K(model), model.focal)}")
        lines.append(f"model {m} ({entry['folder']}/): {entry['registered']} more views: "
                     f"{', '.join(entry['views'])}{focal}")
    for m, entry in enumerate(models):
        gt = entry.get("ground_truth")
        if gt is None:
            continue
        whose = "" if len(models) == 1 else f"{model_name(m, entry['folder'])} "
        lines.append(f"{whose}against ground truth: camera centres within "
                     f"{100 * gt['max_center_error_fraction']:.3f} % of the scene extent, "
                     f"rotations within {gt['max_rotation_error_deg']:.3f} deg"
                     + (f", focal length {100 * gt['focal_error_fraction']:+.2f} %"
                        if "focal_error_fraction" in gt else ""))
    return lines
