"""Self-contained HTML reports of a reconstruction or a calibration.

The reports read results and draw nothing new: numbers from the summaries the commands
write as JSON, shown in words with their units (:mod:`scene3D.report.wording`), figures as
the PNG bytes the commands write, per-view numbers read from a model's observations
(:mod:`scene3D.report.diagnostics`), and for reconstructions an interactive 3D view
(plotly.js from the installed ``plotly`` package, inlined compressed; see
:mod:`scene3D.report.viewer`). Each function returns the page as an :class:`Html`
(``.text()`` is the string); the command writes it with
:func:`scene3D.io.export.atomic_write_pieces` (atomically, with the other outputs).

- :func:`two_view_report`: ``report.html`` of ``chapter4.py`` / ``scene3d reconstruct``;
- :func:`multi_view_report`: ``report.html`` of ``scene3d reconstruct-views``;
- :func:`calibration_report`: ``NAME_report.html`` of ``calibrate.py``.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import ArrayLike

from .. import __version__
from ..calibration.uncertainty import UncertaintyMap
from ..io.colmap_model import ColmapModel
from ..viz.drawing import frustum_corners, robust_extent
from .charts import histogram_svg, shared_points_svg
from .diagnostics import ViewDiagnostics, view_diagnostics
from .page import Html, Markup, Page, esc, format_value, image_data_url
from .viewer import (
    MAX_VIEW_POINTS,
    CameraLayer,
    CloudLayer,
    MissingViewerError,
    PreparedView,
    prepare_view,
)
from .wording import (
    CALIBRATION_NOTES,
    CAMERA_MODELS,
    FIELDS,
    display_path,
    figure_caption,
    matrix_rows,
    quantity_rows,
    stage_name,
)

__all__ = [
    "MAX_VIEW_POINTS", "CameraLayer", "CloudLayer", "Html", "MissingViewerError", "PreparedView",
    "ViewDiagnostics", "calibration_report", "colmap_layers", "colmap_report",
    "colmap_summary", "multi_view_layers", "multi_view_report",
    "prepare_view", "two_view_layers", "two_view_report", "view_diagnostics",
]

# The fields of each section, in order (the wording module says what each one is).
_PAIR_SETUP = ("calibration_source", "image_size", "native_image_size", "feature")
_PAIR_RESULT = ("num_matches", "num_inliers", "num_points", "reprojection_rmse_px",
                "median_parallax_deg")
_PAIR_TRUST = ("trusted", "homography_inlier_ratio", "robust_starts", "robust_spread_deg",
               "focal_scale", "focal_scale_sigma", "focal_ratio", "focal_ratio_sigma",
               "rotation_sigma_deg", "translation_sigma_deg", "noise_sigma_px",
               "noise_cut_share", "behind_share", "flow_gain", "distortion_k",
               "distortion_pose_shift_deg", "focal_px_sigma")
_SELF_CALIBRATION = ("start", "camera", "start_focal_px", "photos_focal_px", "determined")
_VIEWS_RESULT = ("status", "views", "registered", "points", "mean_track_length",
                 "reprojection_rmse_px", "pair_selection", "matched_pairs", "verified_pairs",
                 "feature")
_VIEWS_CAMERA = ("calibration_source", "camera_model", "image_size", "focal_px_sigma")
_GROUND_TRUTH = ("median_center_error_fraction", "max_center_error_fraction",
                 "median_rotation_error_deg", "max_rotation_error_deg", "true_focal_px",
                 "focal_error_fraction")
_MODEL_COLUMNS = ("status", "registered", "points", "mean_track_length",
                  "reprojection_rmse_px")
_RADIAL = ("k1", "k2", "p1", "p2", "k3")


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


def _timings(page: Page, timings: Mapping[str, float] | None) -> None:
    if not timings:
        return
    page.heading("Timings")
    total = timings.get("total")
    rows = [(stage_name(k), f"{float(v):.2f} s") + ((f"{v / total:.0%}",) if total else ())
            for k, v in timings.items() if v is not None]
    page.table(rows, header=("stage", "time") + (("share of the whole run",) if total else ()),
               table_id="timings")
    page.paragraph("Measured by the command (the report itself and the writing of the "
                   "files come after; reconstruction.json has them).", "note")


def _figures(page: Page, figures: Mapping[str, bytes]) -> None:
    if not figures:
        return
    page.heading("Figures")
    for name, png in figures.items():
        page.figure(png, figure_caption(name))


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
    _self_calibration(page, summary.get("self_calibration"))
    if isinstance(summary.get("dense"), dict):
        page.heading("Dense cloud")
        dense = summary["dense"]
        page.quantities([("dense points", FIELDS["num_points"].text(dense.get("num_points")),
                          "points of the dense matching, in the same frame"),
                         *quantity_rows(dense, ("disparity_range_px",))], "dense")
    _view_section(page, view, "Frame: camera 1 (x right, y down, z forward), shown with -y "
                  "up; the baseline has unit length (two views do not fix the scale).")
    _figures(page, figures)
    _timings(page, summary.get("timings_s"))
    page.raw_json(_jsonable(dict(summary)))
    return page.render(_footer())


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


def _self_calibration(page: Page, fields: Any) -> None:
    """The focal length found from the photos, when there was no calibration file."""
    if not isinstance(fields, Mapping) or not fields:
        return
    page.heading("Focal length from the photos")
    page.quantities(quantity_rows(fields, _SELF_CALIBRATION), "self-calibration")


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
    diagnostics: ViewDiagnostics | None = None,
    thumbnails: Mapping[str, bytes] | None = None,
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
    diagnostics : ViewDiagnostics or None, default None
        Per-view numbers (:func:`view_diagnostics`): the views table gains the points each
        view sees and its reprojection error, and the page the histograms and the view
        graph.
    thumbnails : mapping of str to bytes or None, default None
        A small JPEG of each view, by name, shown in the views table.
    """
    page = Page(f"scene3D reconstruction of {len(names)} views")
    in_models = [label for label in placed if label is not None]
    models = len(set(in_models))
    page.verdict(not warnings, f"{len(in_models)} of {len(names)} views registered"
                 + (f" in {models} models" if models > 1 else ""), warnings)
    page.lines(lines)
    page.heading("Result (the largest model)")
    page.quantities(quantity_rows(summary, _VIEWS_RESULT), "numbers")
    _camera_section(page, summary)
    _self_calibration(page, summary.get("self_calibration"))
    if isinstance(summary.get("ground_truth"), dict):
        page.heading("Against the ground truth (the largest model)")
        page.quantities(quantity_rows(summary["ground_truth"], _GROUND_TRUTH), "ground-truth")
    entries = summary.get("models")
    if isinstance(entries, list) and len(entries) > 1:
        page.heading("Models")
        page.table(([_model_label(m, e.get("folder", "")),
                     *(FIELDS[k].text(e.get(k)) for k in _MODEL_COLUMNS)]
                    for m, e in enumerate(entries)),
                   header=("model", *(FIELDS[k].label for k in _MODEL_COLUMNS)),
                   table_id="models")
    _views_section(page, names, placed, summary, diagnostics, thumbnails or {})
    if diagnostics is not None:
        _diagnostic_charts(page, diagnostics)
    _view_section(page, view, "The largest model. Frame: the camera frame of the first view "
                  "of its initial pair (x right, y down, z forward), shown with -y up; the "
                  "scale is arbitrary. The box is fitted to the densest part of the cloud.")
    _figures(page, figures)
    _timings(page, summary.get("timings_s"))
    page.raw_json(_jsonable(dict(summary)))
    return page.render(_footer())


def _model_label(m: int, folder: str) -> str:
    """'the largest (this folder)', 'model 1 (model-1/)'."""
    return "the largest (this folder)" if m == 0 or folder in (".", "") else \
        f"model {m} ({folder}/)"


def _camera_section(page: Page, summary: Mapping[str, Any]) -> None:
    """The camera of a multi-view reconstruction: its model, K and distortion."""
    page.heading("The camera")
    rows = quantity_rows(summary, _VIEWS_CAMERA)
    dist = [float(d) for d in summary.get("distortion", []) or []]
    if any(dist):
        rows.append(("lens distortion", ", ".join(f"{n} {d:+.4f}" for n, d in
                                                   zip(_RADIAL, dist) if d),
                     "OpenCV's coefficients at the working size (k: radial, p: tangential)"))
    page.quantities(rows, "camera")
    if "K" in summary:
        page.matrices({"K (intrinsics, px)": matrix_rows(summary["K"], ".2f")},
                      "fx, fy: focal lengths; cx, cy: the principal point; pixels of the "
                      "working images. Poses: a world point X is at R X + t in a camera's "
                      "frame (cameras.json and colmap/ have each view's R and t).")


def _views_section(page: Page, names: Sequence[str], placed: Sequence[str | None],
                   summary: Mapping[str, Any], diagnostics: ViewDiagnostics | None,
                   thumbnails: Mapping[str, bytes]) -> None:
    """One row per view: thumbnail, model, points seen, errors, or why it is in none."""
    page.heading("Views")
    reasons = summary.get("unregistered_reasons") or {}
    truth = summary.get("ground_truth") if isinstance(summary.get("ground_truth"), dict) \
        else {}
    gt_index = {n: i for i, n in enumerate(truth.get("views", []))}
    centre_q, rot_q = FIELDS["max_center_error_fraction"], FIELDS["max_rotation_error_deg"]
    header = ["", "view", "model"] if thumbnails else ["view", "model"]
    if diagnostics is not None:
        header += ["points seen", "reprojection error (RMS)"]
    if gt_index:
        header += ["camera centre error", "rotation error"]
    rows = []
    for v, (name, label) in enumerate(zip(names, placed)):
        row: list[Any] = []
        if thumbnails:
            jpg = thumbnails.get(name)
            row.append(Markup(f'<img class="thumb" src="{image_data_url(jpg)}" '
                              f'alt="{esc(name)}">') if jpg else "")
        row += [name, label if label is not None else
                f"none: {reasons.get(name, 'reason unknown')}"]
        if diagnostics is not None:
            row += [int(diagnostics.points_seen[v]) if label is not None else "-",
                    FIELDS["reprojection_rmse_px"].text(float(diagnostics.rmse_px[v]))]
        if gt_index:
            i = gt_index.get(name)
            row += ["-", "-"] if i is None else [
                centre_q.text(truth["center_error_fraction_of_extent"][i]),
                rot_q.text(truth["rotation_error_deg"][i])]
        rows.append(row)
    page.table(rows, header=header, table_id="views")
    notes = []
    if diagnostics is not None:
        notes.append("Points seen: the observations of the view in its model. Reprojection "
                     "error: how far, per coordinate, those points land from where they "
                     "were measured in the view.")
    if gt_index:
        notes.append("Ground truth: the distance from the true camera centre as a share of "
                     "the scene's extent, and the angle from the true rotation, after the "
                     "best similarity.")
    if notes:
        page.paragraph(" ".join(notes), "note")


def _diagnostic_charts(page: Page, d: ViewDiagnostics) -> None:
    """Histograms of track length and reprojection error, and the view graph."""
    page.heading("Tracks and errors (the largest model)")
    page.open_row()
    if len(d.track_lengths):
        longest = int(d.track_lengths.max())
        cap = min(longest, 15)  # longer tracks are counted in the last bar
        lengths = np.minimum(d.track_lengths, cap)
        counts = np.bincount(lengths, minlength=cap + 1)[2:]
        ticks = [str(n) for n in range(2, cap + 1)]
        if longest > cap:
            ticks[-1] = f"{cap}+"
        page.svg(histogram_svg(counts, np.arange(2, cap + 2), "views that see the point",
                               "points", tick_labels=ticks),
                 "Track length: how many views see each 3D point.")
    if len(d.errors_px):
        top = float(np.quantile(d.errors_px, 0.99)) or 1.0
        counts, edges = np.histogram(np.minimum(d.errors_px, top), bins=30, range=(0, top))
        page.svg(histogram_svg(counts, edges, "reprojection error (px)", "observations"),
                 "Reprojection error: the distance of each observation from its point's "
                 "projection (errors beyond the 99th percentile in the last bar).")
    page.close_row()
    page.heading("View graph")
    page.svg(shared_points_svg(d.names, d.shared_points),
             "Points each pair of views shares in the model (darker: more; hover for the "
             "count). Pairs that share none are blank.")


def colmap_layers(model: ColmapModel) -> tuple[list[CloudLayer], CameraLayer]:
    """What the 3D view of a COLMAP model shows (for :func:`prepare_view`): its points and
    a frustum per image, each with its own camera.

    Parameters
    ----------
    model : ColmapModel
        World-to-camera poses, points in the world frame.

    Returns
    -------
    layers : list of CloudLayer
    cameras : CameraLayer
    """
    depth = _frusta_depth(model.points3d, model.centers)
    corners = np.full((len(model.names), 5, 3), np.nan)
    for camera_id, camera in model.cameras.items():
        mine = np.flatnonzero(model.camera_ids == camera_id)
        if mine.size:
            corners[mine] = frustum_corners(model.R[mine], model.t[mine], camera.K,
                                            camera.image_size, depth)
    return ([CloudLayer("points", model.points3d, model.colors, 2.5)],
            CameraLayer(tuple(model.names), corners))


def colmap_summary(model: ColmapModel) -> dict:
    """The numbers of a COLMAP model as a report shows them (and its JSON block holds).

    Parameters
    ----------
    model : ColmapModel

    Returns
    -------
    dict
        ``views``, ``points``, ``mean_track_length``, ``reprojection_rmse_px`` (RMS per
        coordinate, with each image's camera, distortion included) and ``cameras`` (by id:
        ``model``, ``image_size``, ``params``).
    """
    errors = model.reprojection_errors_px()
    rmse = float(np.sqrt(np.mean(errors ** 2) / 2)) if errors.size else float("nan")
    return {
        "views": len(model.names), "registered": len(model.names),
        "points": len(model.points3d),
        "mean_track_length": len(model.obs_view) / max(len(model.points3d), 1),
        "reprojection_rmse_px": rmse,
        "cameras": {str(i): {"model": c.model, "image_size": list(c.image_size),
                             "params": list(c.params)} for i, c in model.cameras.items()},
    }


def colmap_report(model: ColmapModel, source: str,
                  thumbnails: Mapping[str, bytes] | None = None) -> Html:
    """The page of a COLMAP model read from disk (``scene3d report MODEL_DIR``).

    Parameters
    ----------
    model : ColmapModel
        :func:`scene3D.io.colmap.read_colmap_text`'s model.
    source : str
        Where it was read from, as the user named it (the title).
    thumbnails : mapping of str to bytes or None, default None
        A small JPEG of each image, by name.

    Returns
    -------
    Html
    """
    summary = colmap_summary(model)
    page = Page(f"scene3D report of the COLMAP model {display_path(source)}")
    page.verdict(True, f"{len(model.names)} images, {len(model.points3d)} points, "
                 f"{len(model.cameras)} camera{'s' if len(model.cameras) != 1 else ''}")
    page.heading("Result")
    page.quantities(quantity_rows(summary, ("views", "points", "mean_track_length",
                                            "reprojection_rmse_px")), "numbers")
    page.heading("Cameras")
    page.table(((i, CAMERA_MODELS.get(c.model.lower(), c.model),
                 f"{c.image_size[0]} x {c.image_size[1]} px",
                 ", ".join(f"{v:.6g}" for v in c.params))
                for i, c in model.cameras.items()),
               header=("camera", "model", "image size", "parameters (COLMAP's order)"),
               table_id="cameras")
    page.paragraph("COLMAP's parameter order: f or fx, fy, then cx, cy, then the distortion "
                   "coefficients. Poses: a world point X is at R X + t in a camera's frame "
                   "(images.txt has each image's rotation as a quaternion and t).", "note")
    diagnostics = view_diagnostics(model.names, [model])
    _views_section(page, model.names, ["the model"] * len(model.names), {}, diagnostics,
                   thumbnails or {})
    _diagnostic_charts(page, diagnostics)
    _view_section(page, prepare_view(*colmap_layers(model)), "Frame: the model's world "
                  "frame, shown with -y up (COLMAP's cameras look along +z with y down).")
    page.raw_json(_jsonable(summary))
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
    _figures(page, figures)
    return page.render(_footer())
