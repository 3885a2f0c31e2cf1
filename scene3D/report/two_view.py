"""The page of a two-view reconstruction (``chapter4.py``, ``scene3d reconstruct``)."""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import ArrayLike

from ..viz.drawing import frustum_corners
from .page import Html, Page
from .sections import (
    figures_section,
    footer,
    frusta_depth,
    jsonable,
    self_calibration_section,
    timings_section,
    view_section,
)
from .viewer import CameraLayer, CloudLayer, PreparedView
from .wording import FIELDS, display_path, matrix_rows, quantity_rows

__all__ = ["two_view_layers", "two_view_report"]

# The fields of each section, in order (the wording module says what each one is).
_PAIR_SETUP = ("calibration_source", "image_size", "native_image_size", "feature")
_PAIR_RESULT = ("num_matches", "num_inliers", "num_points", "reprojection_rmse_px",
                "median_parallax_deg")
_PAIR_TRUST = ("trusted", "homography_inlier_ratio", "robust_starts", "robust_spread_deg",
               "focal_scale", "focal_scale_sigma", "focal_ratio", "focal_ratio_sigma",
               "rotation_sigma_deg", "translation_sigma_deg", "noise_sigma_px",
               "noise_cut_share", "behind_share", "flow_gain", "distortion_k",
               "distortion_pose_shift_deg", "focal_px_sigma")


def two_view_layers(
    points3d: ArrayLike,
    colors: ArrayLike | None,
    R: ArrayLike,
    t: ArrayLike,
    K: ArrayLike,
    image_size: tuple[int, int],
    dense_points: ArrayLike | None = None,
    dense_colors: ArrayLike | None = None,
) -> tuple[list[CloudLayer], CameraLayer]:
    """What the 3D view of a two-view reconstruction shows (for :func:`prepare_view`).

    Parameters
    ----------
    points3d : (N, 3) array_like
        The sparse cloud in the camera-1 frame; ``colors`` its RGB ``uint8``.
    R, t : (3, 3), (3,) array_like
        Camera 2's pose, ``x_cam2 = R x_cam1 + t``.
    K : (3, 3) array_like
        Intrinsics of the working images, of size ``image_size`` (width, height).
    dense_points, dense_colors : optional
        The dense cloud (:func:`scene3D.dense.dense_point_cloud`), same frame.
    """
    points3d = np.asarray(points3d, dtype=np.float64).reshape(-1, 3)
    poses_R = np.stack([np.eye(3), np.asarray(R, dtype=np.float64)])
    poses_t = np.stack([np.zeros(3), np.asarray(t, dtype=np.float64).reshape(3)])
    layers = [CloudLayer("sparse", points3d, None if colors is None else np.asarray(colors),
                         4.0 if dense_points is None else 3.0)]
    if dense_points is not None:
        layers.append(CloudLayer("dense", np.asarray(dense_points, dtype=np.float64),
                                 None if dense_colors is None else np.asarray(dense_colors),
                                 1.5))
    depth = frusta_depth(points3d, poses_t)
    cameras = CameraLayer(("camera 1", "camera 2"),
                          frustum_corners(poses_R, poses_t, np.asarray(K, dtype=np.float64),
                                          image_size, depth))
    return layers, cameras


def two_view_report(
    summary: Mapping[str, Any],
    lines: Sequence[str],
    figures: Mapping[str, bytes],
    view: PreparedView,
) -> Html:
    """The page of a two-view reconstruction.

    Parameters
    ----------
    summary : mapping
        What ``reconstruction.json`` holds (``trusted``, ``warnings``, ``timings_s`` and the
        numbers are read from it; every field is in the page's JSON block).
    lines : sequence of str
        The command's result lines (what it prints).
    figures : mapping of str to bytes
        File name to PNG or JPEG bytes, in display order.
    view : PreparedView
        ``prepare_view(*two_view_layers(...))``.
    """
    inputs = summary.get("inputs", {})
    image1, image2 = inputs.get("image1", "image 1"), inputs.get("image2", "image 2")
    page = Page(f"scene3D reconstruction: {Path(image1).name} + {Path(image2).name}")
    trusted = bool(summary.get("trusted", True))
    page.verdict(trusted, "Trusted result" if trusted else "The pose may not be trustworthy",
                 summary.get("warnings", []))
    page.lines(lines)
    page.heading("Inputs")
    files = [("photo 1", display_path(image1), ""), ("photo 2", display_path(image2), "")]
    if inputs.get("calibration"):
        files.append(("calibration file", display_path(inputs["calibration"]), ""))
    page.quantities(files + quantity_rows(summary, _PAIR_SETUP), "inputs")
    page.heading("Result")
    page.quantities(quantity_rows(summary, _PAIR_RESULT), "numbers")
    if "R" in summary and "t" in summary:
        _pose_section(page, summary)
    page.heading("Trust and uncertainty")
    page.quantities(quantity_rows(summary, _PAIR_TRUST), "trust")
    self_calibration_section(page, summary.get("self_calibration"))
    if isinstance(summary.get("dense"), dict):
        page.heading("Dense cloud")
        dense = summary["dense"]
        page.quantities([("dense points", FIELDS["num_points"].text(dense.get("num_points")),
                          "points of the dense matching, in the same frame"),
                         *quantity_rows(dense, ("disparity_range_px",))], "dense")
    view_section(page, view, "Frame: camera 1 (x right, y down, z forward), shown with -y "
                  "up; the baseline has unit length (two views do not fix the scale).")
    figures_section(page, figures)
    timings_section(page, summary.get("timings_s"))
    page.raw_json(jsonable(dict(summary)))
    return page.render(footer())


def _pose_section(page: Page, summary: Mapping[str, Any]) -> None:
    """Camera 2's R, t and centre, and K, as matrices (the two-view report)."""
    R = np.asarray(summary["R"], dtype=np.float64)
    t = np.asarray(summary["t"], dtype=np.float64).reshape(3)
    page.heading("Camera 2's pose and the camera")
    named = {"R (rotation)": matrix_rows(R), "t (translation, unit length)":
             matrix_rows(t[:, None]), "camera 2's centre, -R^T t": matrix_rows((-R.T @ t)[:, None])}
    if "K" in summary:
        named["K (intrinsics, px)"] = matrix_rows(summary["K"], ".2f")
    page.matrices(named, "A point x in camera 1's frame (x right, y down, z forward) is at "
                  "R x + t in camera 2's. Camera model: pinhole, K "
                  "at the working image size, the photos undistorted with the calibration's "
                  "lens distortion before matching.")
