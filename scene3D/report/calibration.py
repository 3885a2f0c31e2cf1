"""The page of a camera calibration (``calibrate.py``, ``scene3d calibrate``)."""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np

from ..calibration.uncertainty import UncertaintyMap
from .page import Html, Page, format_value
from .sections import figures_section, footer
from .wording import CALIBRATION_NOTES

__all__ = ["calibration_report"]


def calibration_report(
    lines: Sequence[str],
    numbers: Mapping[str, Any],
    per_view_errors_px: Mapping[str, float],
    rejected_views: Mapping[str, float],
    warnings: Sequence[str],
    umap: UncertaintyMap,
    figures: Mapping[str, bytes],
) -> Html:
    """The page of a calibration.

    Parameters
    ----------
    lines : sequence of str
        The command's result lines (what it prints).
    numbers : mapping
        Named values (RMS, intrinsics with their standard deviations, noise...).
    per_view_errors_px, rejected_views : mapping of str to float
        RMS error of each kept view, and of each view dropped as an outlier.
    warnings : sequence of str
        Coverage and uncertainty warnings.
    umap : UncertaintyMap
        The projection-uncertainty map (its numbers; its picture is among ``figures``).
    figures : mapping of str to bytes
        File name to PNG bytes.
    """
    page = Page("scene3D camera calibration")
    page.verdict(not warnings, "No warnings" if not warnings else "Warnings", warnings)
    page.lines(lines)
    page.heading("Calibration")
    page.quantities([(k, format_value(v), CALIBRATION_NOTES.get(k.split(" (")[0], ""))
                     for k, v in numbers.items()], "numbers")
    page.paragraph("Camera model: OpenCV's pinhole camera, K = [[fx, 0, cx], [0, fy, cy], "
                   "[0, 0, 1]] in pixels of these images, with its radial (k1, k2, k3 and, "
                   "with the rational model, k4 to k6) and tangential (p1, p2) lens "
                   "distortion. +- is 1 sigma.", "note")
    page.heading("Projection uncertainty")
    page.paragraph(
        "1 sigma error, in the worst direction, of projecting a point fixed in the camera "
        "frame with these intrinsics, propagated from the full covariance of the intrinsics "
        "and distortion (the board poses marginalised out) and the corner noise the "
        "residuals show. It does not include the uncertainty of the camera frame itself "
        "(mrcal's method removes that part) nor model errors.", "note")
    def px(value: float) -> float | str:  # the page formats numbers; no ray, no number
        return "no ray" if np.isnan(value) else value

    page.key_values({"median (px)": px(umap.median_px), "worst (px)": px(umap.worst_px),
                     "centre (px)": px(umap.centre_px),
                     **{f"{k} corner (px)": px(v) for k, v in umap.corners_px.items()},
                     "share that no ray reaches": f"{umap.unreachable_share:.1%}",
                     "corner limit (px)": umap.limit_px}, "uncertainty")
    page.heading("Per-view error")
    rows = [(n, e, "kept") for n, e in per_view_errors_px.items()]
    rows += [(n, e, "dropped as an outlier") for n, e in rejected_views.items()]
    page.table(rows, header=("view", "RMS reprojection error (px)", "status"),
               table_id="views")
    figures_section(page, figures)
    return page.render(footer())
