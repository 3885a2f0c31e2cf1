"""A pair's result as the summary ``chapter4.py`` writes to ``reconstruction.json``: one dict of
JSON-ready values (arrays stay arrays; :func:`scene3D.io.export.write_json` lists them).
"""

from __future__ import annotations

from collections.abc import Mapping
from pathlib import Path
from typing import TYPE_CHECKING

from .. import __version__

if TYPE_CHECKING:
    from ..dense import DenseReconstruction
    from ..geometry.intrinsics_prior import FocalPrior
    from ..selfcalibration.pair import SelfCalibration
    from .results import TwoViewGeometry

#: What ``pose_covariance`` means, written beside it.
POSE_COVARIANCE_DOC = (
    "pose_covariance in radians^2 of (w, d) for the poses exp([w]x) R (w in the camera-2 "
    "frame, rows 0-2) and (t + d @ pose_covariance_basis) / |t + d @ pose_covariance_basis| "
    "(rows 3-4); rotation_sigma_deg and translation_sigma_deg are the square roots of the "
    "largest eigenvalues of its two blocks, in degrees")


def calibration_fields(calibration: SelfCalibration | None,
                       prior: FocalPrior | None = None) -> dict:
    """The summary's calibration fields: where the final ``K`` comes from and how sure it is.

    Parameters
    ----------
    calibration : SelfCalibration or None
        The pair's self-calibration (:func:`scene3D.selfcalibration.self_calibrate_pair`), or
        None when ``K`` came from a calibration file.
    prior : FocalPrior, optional
        The EXIF or default focal prior it started from.

    Returns
    -------
    dict
        ``calibration_source``, ``focal_px_sigma`` and ``self_calibration`` (None with a
        calibration file; else the start, the photos' estimate, the candidates and the time).
    """
    if calibration is None:
        return {"calibration_source": "file", "focal_px_sigma": None, "self_calibration": None}
    return {
        "calibration_source": calibration.source,
        "focal_px_sigma": calibration.focal_sigma_px,
        "self_calibration": {
            "start": prior.description if prior is not None else None,
            "camera": prior.camera_name if prior is not None else None,
            "start_focal_px": calibration.start_focal_px,
            "start_sigma_log": calibration.start_sigma_log,
            "photos_focal_px": calibration.data_focal_px,
            "photos_sigma_log": calibration.data_sigma_log,
            "photos_sigma_parts_log": calibration.uncertainty._asdict(),
            "determined": calibration.determined,
            "candidates_px": [focal for focal, _ in calibration.candidates],
            "iterations": calibration.iterations,
            "seconds": calibration.seconds,
            "exif_warnings": list(prior.warnings) if prior is not None else [],
        },
    }


def pair_summary(result: TwoViewGeometry, image_paths: tuple[Path, Path],
                 image_size: tuple[int, int], native_size: tuple[int, int],
                 feature_requested: str, timings: Mapping[str, float],
                 calibration_path: Path | None = None,
                 self_calibration: SelfCalibration | None = None,
                 prior: FocalPrior | None = None,
                 dense: DenseReconstruction | None = None) -> dict:
    """The pair's summary: inputs, pose, intrinsics, uncertainty, trust and timings.

    Parameters
    ----------
    result : TwoViewGeometry
        The pair's reconstruction (:meth:`scene3D.SceneReconstruction3D.reconstruct`).
    image_paths : (Path, Path)
        The two photos.
    image_size : (int, int)
        ``(width, height)`` of the working images.
    native_size : (int, int)
        ``(width, height)`` of the photos as stored.
    feature_requested : str
        The feature mode asked for (``result.feature`` says which ran).
    timings : Mapping of str to float
        Seconds per stage.
    calibration_path : Path, optional
        The calibration file, or None when the pair self-calibrated.
    self_calibration : SelfCalibration, optional
        The self-calibration, when there was one (:func:`calibration_fields`).
    prior : FocalPrior, optional
        Its starting prior.
    dense : DenseReconstruction, optional
        The rectified pair's dense cloud: its point count and disparity range are added.

    Returns
    -------
    dict
        The fields of ``reconstruction.json`` but the list of files written.
    """
    summary = {
        "scene3D_version": __version__,
        "conventions": "x_cam2 = R @ x_cam1 + t; |t| = 1 (scale unknown); points3d in the "
                       "camera-1 frame; pixels with integer coordinates at pixel centres; "
                       + POSE_COVARIANCE_DOC,
        "inputs": {"image1": str(image_paths[0]), "image2": str(image_paths[1]),
                   "calibration": None if calibration_path is None else str(calibration_path)},
        "R": result.R, "t": result.t, "K": result.K,
        **calibration_fields(self_calibration, prior),
        "image_size": list(image_size),
        "native_image_size": list(native_size),
        "feature": result.feature, "feature_requested": feature_requested,
        "num_matches": result.num_matches, "num_inliers": result.num_inliers,
        "num_points": result.num_points,
        "reprojection_rmse_px": result.reprojection_rmse_px,
        "median_parallax_deg": result.median_parallax_deg,
        "homography_inlier_ratio": result.homography_inlier_ratio,
        "robust_starts": result.robust_starts, "robust_spread_deg": result.robust_spread_deg,
        "focal_scale": result.focal_scale, "focal_scale_sigma": result.focal_scale_sigma,
        "focal_ratio": result.focal_ratio, "focal_ratio_sigma": result.focal_ratio_sigma,
        "rotation_sigma_deg": result.rotation_sigma_deg,
        "translation_sigma_deg": result.translation_sigma_deg,
        "pose_covariance": result.pose_covariance,
        "pose_covariance_basis": result.pose_uncertainty.basis,
        "noise_sigma_px": result.noise_sigma_px, "noise_cut_share": result.noise_cut_share,
        "behind_share": result.behind_share, "flow_gain": result.flow_gain,
        "distortion_k": result.distortion_k,
        "distortion_pose_shift_deg": result.distortion_pose_shift_deg,
        "trusted": result.trusted, "warnings": list(result.warnings),
        "timings_s": dict(timings),
    }
    if dense is not None:
        summary["dense"] = {"num_points": dense.num_points,
                            "disparity_range_px": list(dense.disparity_range)}
    return summary
