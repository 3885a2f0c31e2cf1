"""Self-contained HTML reports of a reconstruction or a calibration.

The reports read results and draw nothing new: numbers from the summaries the commands
write as JSON, figures as the PNG bytes the commands write, and for reconstructions an
interactive 3D view (plotly.js from the installed ``plotly`` package, inlined; see
:mod:`scene3D.report.viewer`). Each function returns the page as an :class:`Html`
(``.text()`` is the string); the command writes it with
:func:`scene3D.io.export.atomic_write_pieces` (atomically, with the other outputs), which
copies plotly.js from its file.

- :func:`two_view_report`: ``report.html`` of ``chapter4.py`` / ``scene3d reconstruct``;
- :func:`multi_view_report`: ``report.html`` of ``scene3d reconstruct-views``;
- :func:`calibration_report`: ``NAME_report.html`` of ``calibrate.py``.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np
from numpy.typing import ArrayLike

from .. import __version__
from ..calibration.uncertainty import UncertaintyMap
from ..viz.drawing import frustum_corners, robust_extent
from .page import Html, Page
from .viewer import (
    MAX_VIEW_POINTS,
    CameraLayer,
    CloudLayer,
    MissingViewerError,
    PreparedView,
    prepare_view,
)

__all__ = [
    "MAX_VIEW_POINTS", "CameraLayer", "CloudLayer", "Html", "MissingViewerError", "PreparedView",
    "calibration_report", "multi_view_layers", "multi_view_report", "prepare_view",
    "two_view_layers", "two_view_report",
]

# Summary fields that describe trust and uncertainty (shown in their own table).
_TRUST_WORDS = ("trusted", "sigma", "spread", "std", "uncertainty", "focal_scale",
                "robust_starts", "homography_inlier_ratio", "parallax")
# Fields shown elsewhere (or only in the JSON block).
_SKIPPED = {"R", "t", "K", "timings_s", "warnings", "conventions", "scene3D_version", "inputs",
            "unregistered", "ground_truth", "dense"}


def _frusta_depth(points3d: np.ndarray, centres: np.ndarray) -> float:
    """Frustum depth for display: 8 % of the cloud's robust extent (or of the cameras')."""
    lo, hi = robust_extent(points3d if len(points3d) else centres)
    return 0.08 * max(float(np.linalg.norm(hi - lo)), 1e-9)


def _view_section(page: Page, view: PreparedView, frame_note: str) -> None:
    page.heading("3D view")
    notes = [f"Drag to turn, scroll to zoom, click a legend entry to hide it. "
             f"{view.num_points:,} points (plotly.js {view.version})."] + view.notes
    page.view3d(view.plotly_js, view.figure_json, notes)
    page.paragraph(frame_note, "note")


def _scalars(summary: Mapping[str, Any]) -> tuple[dict[str, Any], dict[str, Any]]:
    """The summary's scalar and short-list fields, split into (result, trust)."""
    result, trust = {}, {}
    for key, value in summary.items():
        if key in _SKIPPED or isinstance(value, dict) or _is_records(value):
            continue
        if isinstance(value, (list, tuple, np.ndarray)) and np.size(value) > 4:
            continue
        target = trust if any(w in key for w in _TRUST_WORDS) else result
        target[key] = value.tolist() if isinstance(value, np.ndarray) else value
    return result, trust


def _is_records(value: Any) -> bool:
    """A list of dicts (such as a multi-view summary's ``models``): a table of its own."""
    return isinstance(value, (list, tuple)) and any(isinstance(v, dict) for v in value)


def _records_table(page: Page, records: Sequence[Mapping[str, Any]], table_id: str) -> None:
    """One row per record, one column per field that holds a scalar in some record."""
    columns = list(dict.fromkeys(
        k for r in records for k, v in r.items()
        if v is None or isinstance(v, (str, int, float, bool, np.integer, np.floating))))
    page.table(([r.get(k) for k in columns] for r in records), header=columns,
               table_id=table_id)


def _timings(page: Page, timings: Mapping[str, float] | None) -> None:
    if not timings:
        return
    page.heading("Timings")
    total = timings.get("total")
    rows = [(k, float(v)) + ((f"{v / total:.0%}",) if total else ())
            for k, v in timings.items() if v is not None]
    page.table(rows, header=("stage", "seconds") + (("share of total",) if total else ()),
               table_id="timings")
    page.paragraph("Seconds of this run, measured by the command (the report itself and the "
                   "writing of the files come after; reconstruction.json has them).", "note")


def _figures(page: Page, figures: Mapping[str, bytes]) -> None:
    if not figures:
        return
    page.heading("Figures")
    for name, png in figures.items():
        page.figure(png, name)


def _jsonable(value: Any) -> Any:
    if isinstance(value, np.ndarray):
        return value.tolist()
    if isinstance(value, (np.floating, np.integer, np.bool_)):
        return value.item()
    if isinstance(value, dict):
        return {str(k): _jsonable(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [_jsonable(v) for v in value]
    return value


def _footer(extra: str = "") -> str:
    return (f"scene3D {__version__}. A self-contained file: it loads nothing from the "
            f"network. {extra}").strip()


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
    depth = _frusta_depth(points3d, poses_t)
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
    page = Page(f"scene3D reconstruction: {inputs.get('image1', 'image 1')} + "
                f"{inputs.get('image2', 'image 2')}")
    page.lines(lines)
    trusted = bool(summary.get("trusted", True))
    page.verdict(trusted, "Trusted result" if trusted else "The pose may not be trustworthy",
                 summary.get("warnings", []))
    result, trust = _scalars(summary)
    page.heading("Result")
    page.key_values(result, "numbers")
    page.heading("Trust and uncertainty")
    page.key_values(trust, "trust")
    if isinstance(summary.get("dense"), dict):
        page.heading("Dense cloud")
        page.key_values(summary["dense"], "dense")
    _view_section(page, view, "Frame: camera 1 (x right, y down, z forward), shown with -y "
                  "up; the baseline has unit length (two views do not fix the scale).")
    _figures(page, figures)
    _timings(page, summary.get("timings_s"))
    page.raw_json(_jsonable(dict(summary)))
    return page.render(_footer())


def multi_view_layers(
    names: Sequence[str],
    K: ArrayLike,
    image_size: tuple[int, int],
    registered: ArrayLike,
    R: ArrayLike,
    t: ArrayLike,
    points3d: ArrayLike,
    colors: ArrayLike | None,
) -> tuple[list[CloudLayer], CameraLayer]:
    """What the 3D view of a multi-view reconstruction shows (for :func:`prepare_view`).

    Parameters
    ----------
    names : sequence of str
        One per view.
    K : (3, 3) array_like
        Intrinsics of the working images, of size ``image_size`` (width, height).
    registered : (V,) bool array_like
    R, t : (V, 3, 3), (V, 3) array_like
        World-to-camera poses (NaN for views not registered).
    points3d : (P, 3) array_like
        World points; ``colors`` their RGB ``uint8``.
    """
    points3d = np.asarray(points3d, dtype=np.float64).reshape(-1, 3)
    R = np.asarray(R, dtype=np.float64).reshape(-1, 3, 3)
    t = np.asarray(t, dtype=np.float64).reshape(-1, 3)
    registered = np.asarray(registered, dtype=bool)
    R_reg, t_reg = R[registered], t[registered]
    centres = -np.einsum("vji,vj->vi", R_reg, t_reg)
    corners = np.full((len(names), 5, 3), np.nan)
    if registered.any():
        corners[registered] = frustum_corners(R_reg, t_reg, np.asarray(K, dtype=np.float64),
                                              image_size, _frusta_depth(points3d, centres))
    layer = CloudLayer("points", points3d, None if colors is None else np.asarray(colors), 2.5)
    return [layer], CameraLayer(tuple(names), corners)


def multi_view_report(
    names: Sequence[str],
    placed: Sequence[str | None],
    summary: Mapping[str, Any],
    lines: Sequence[str],
    warnings: Sequence[str],
    figures: Mapping[str, bytes],
    view: PreparedView,
) -> Html:
    """The page of a multi-view reconstruction.

    Parameters
    ----------
    names : sequence of str
        One per view.
    placed : sequence of str or None
        One per view: the model it is in (e.g. ``"the largest model"``, ``"model-1/"``), or
        None when it is in none (``summary["unregistered_reasons"]`` says why).
    summary : mapping
        What ``reconstruction.json`` holds.
    lines : sequence of str
        The command's result lines.
    warnings : sequence of str
        The command's warnings (views in no model among them); none gives the "ok" verdict.
    figures : mapping of str to bytes
        File name to PNG or JPEG bytes.
    view : PreparedView
        ``prepare_view(*multi_view_layers(...))``: the largest model.
    """
    page = Page(f"scene3D reconstruction of {len(names)} views")
    page.lines(lines)
    in_models = [label for label in placed if label is not None]
    models = len(set(in_models))
    page.verdict(not warnings, f"{len(in_models)} of {len(names)} views registered"
                 + (f" in {models} models" if models > 1 else ""), warnings)
    result, trust = _scalars(summary)
    page.heading("Result")
    page.key_values({**result, **trust}, "numbers")
    if _is_records(summary.get("models")):
        page.heading("Models")
        _records_table(page, summary["models"], "models")
    if isinstance(summary.get("ground_truth"), dict):
        page.heading("Against the ground truth (the largest model)")
        page.key_values({k: v for k, v in summary["ground_truth"].items()
                         if not isinstance(v, (list, tuple, np.ndarray))}, "ground-truth")
    _view_section(page, view, "The largest model. Frame: the camera frame of the first view "
                  "of its initial pair (x right, y down, z forward), shown with -y up; the "
                  "scale is arbitrary.")
    page.heading("Views")
    reasons = summary.get("unregistered_reasons") or {}
    page.table(((n, f"in {label}" if label is not None else
                 f"not registered: {reasons.get(n, 'unknown')}")
                for n, label in zip(names, placed)), header=("view", "status"),
               table_id="views")
    _figures(page, figures)
    _timings(page, summary.get("timings_s"))
    page.raw_json(_jsonable(dict(summary)))
    return page.render(_footer())


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
    page.lines(lines)
    page.verdict(not warnings, "No warnings" if not warnings else "Warnings", warnings)
    page.heading("Calibration")
    page.key_values(numbers, "numbers")
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
    _figures(page, figures)
    return page.render(_footer())
