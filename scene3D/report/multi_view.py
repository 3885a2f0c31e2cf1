"""The pages of a multi-view reconstruction (``scene3d reconstruct-views``) and of a COLMAP
model read from disk (``scene3d report``): the numbers, the camera, the views table, the
histograms, the view graph and the 3D view."""

from __future__ import annotations

import dataclasses
from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np
from numpy.typing import ArrayLike

from ..densify.fusion import DenseCloud
from ..io.colmap_model import ColmapModel
from ..viz.drawing import frustum_corners
from .charts import histogram_svg, shared_points_svg
from .dense import DenseRun, dense_clouds, dense_meshes, dense_section
from .diagnostics import (
    ViewDiagnostics,
    grouped_view_graph,
    verified_inlier_matrix,
    view_diagnostics,
)
from .page import Html, Markup, Page, esc, image_data_url
from .sections import (
    figures_section,
    footer,
    frusta_depth,
    jsonable,
    self_calibration_section,
    timings_section,
    view_section,
)
from .viewer import CameraLayer, CloudLayer, PreparedView, prepare_view
from .wording import CAMERA_MODELS, FIELDS, display_path, matrix_rows, quantity_rows

__all__ = ["colmap_layers", "colmap_report", "colmap_summary", "multi_view_layers",
           "multi_view_report", "reconstruction_report"]

# The fields of each section, in order (the wording module says what each one is).
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


def multi_view_layers(
    names: Sequence[str],
    K: ArrayLike,
    image_size: tuple[int, int],
    registered: ArrayLike,
    R: ArrayLike,
    t: ArrayLike,
    points3d: ArrayLike,
    colors: ArrayLike | None,
    dense: DenseRun | DenseCloud | None = None,
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
    dense : DenseRun, DenseCloud or None, default None
        A dense cloud in the same frame: a layer after the sparse points (which the view
        keeps whole; the dense one is thinned to the rest of its bound). A run's mesh is
        not a cloud: :func:`~scene3D.report.dense.dense_meshes` gives it.
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
                                              image_size, frusta_depth(points3d, centres))
    layer = CloudLayer("points" if dense is None else "sparse", points3d,
                       None if colors is None else np.asarray(colors), 2.5)
    return [layer, *dense_clouds(dense)], CameraLayer(tuple(names), corners)


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
    dense: DenseRun | None = None,
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
    dense : DenseRun or None, default None
        The dense run of the largest model: its numbers and depth maps (``view`` holds its
        cloud, :func:`multi_view_layers`).
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
    self_calibration_section(page, summary.get("self_calibration"))
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
    if dense is not None:
        dense_section(page, dense)
    view_section(page, view, "The largest model. Frame: the camera frame of the first view "
                  "of its initial pair (x right, y down, z forward), shown with -y up; the "
                  "scale is arbitrary. The box is fitted to the densest part of the cloud.")
    figures_section(page, figures)
    timings_section(page, summary.get("timings_s"))
    page.raw_json(jsonable(dict(summary)))
    return page.render(footer())


def reconstruction_report(
    recon: Any,
    placed: Sequence[str | None],
    summary: Mapping[str, Any],
    lines: Sequence[str],
    warnings: Sequence[str],
    figures: Mapping[str, bytes],
    thumbnails: Mapping[str, bytes] | None = None,
    dense: DenseRun | None = None,
) -> Html:
    """:func:`multi_view_report` of a reconstruction in memory: its 3D view (the largest
    model, with the dense cloud when there is one) and per-view numbers read from it.

    Parameters
    ----------
    recon : MultiViewReconstruction
        :func:`scene3D.multiview.reconstruct_views`'s result; ``recon.names`` name the views.
    placed, summary, lines, warnings, figures, thumbnails, dense
        As :func:`multi_view_report` takes them.

    Returns
    -------
    Html
    """
    view = prepare_view(*multi_view_layers(
        recon.names, recon.K, recon.image_size, recon.registered, recon.R, recon.t,
        recon.points3d, recon.colors, dense), meshes=dense_meshes(dense))
    # The working images' pixels (photos=False), as the summary's reprojection errors.
    diagnostics = view_diagnostics(recon.names, [recon.colmap_model(m, photos=False)
                                                 for m in recon.models])
    if recon.verified_edges:
        diagnostics = dataclasses.replace(diagnostics, verified_inliers=verified_inlier_matrix(
            recon.verified_edges, len(recon.names)))
    return multi_view_report(recon.names, placed, summary, lines, warnings, figures, view,
                             diagnostics, thumbnails, dense)


def _model_label(m: int, folder: str) -> str:
    """'the largest (this folder)', 'model 1 (model-1/)'."""
    return "the largest (this folder)" if m == 0 or folder in (".", "") else \
        f"model {m} ({folder}/)"


def _camera_section(page: Page, summary: Mapping[str, Any]) -> None:
    """The camera of a multi-view reconstruction: its model, K and distortion; with
    several cameras, one line each first, then the reference camera's details."""
    cameras = summary.get("cameras") or []
    if len(cameras) > 1:
        page.heading("The cameras")
        page.quantities([(
            f"camera {c['camera']}",
            f"{c['photo_size'][0]} x {c['photo_size'][1]} px, focal length "
            f"{c['focal_px_photo']:.1f} px" + (f", k1 {c['distortion'][0]:+.4f}"
                                              if c["distortion"] and c["distortion"][0] else "")
            + ("" if c["estimated"] else " (in no view of the largest model: as it started)"),
            "at the photos' size; its views: " + ", ".join(c["views"]))
            for c in cameras], "cameras")
        reference = next((c["camera"] for c in cameras if c.get("reference")), 1)
        page.heading(f"Camera {reference}, the reference camera")
    else:
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
    if thumbnails and len(thumbnails) < len(names):
        notes.append(f"Thumbnails of {len(thumbnails)} of the {len(names)} views, evenly "
                     "spaced in the input order, to keep the page small.")
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
    labels, shared, group = grouped_view_graph(d.names, d.shared_points)
    grouped = (f" The {len(d.names)} views are grouped {group} at a time, in the input "
               "order: a cell sums the points two groups share." if group > 1 else "")
    page.open_row()
    page.svg(shared_points_svg(labels, shared),
             "Points each pair of views shares in the model (darker: more; hover for the "
             "count). Pairs that share none are blank." + grouped)
    if d.verified_inliers is not None:
        inliers = grouped_view_graph(d.names, d.verified_inliers)[1]
        page.svg(shared_points_svg(labels, inliers, unit="inliers"),
                 "The pairs whose matches verified: enough of them fit one essential matrix "
                 "(darker: more inliers; hover for the count). Pairs not verified are blank."
                 + grouped)
    page.close_row()


def colmap_layers(model: ColmapModel, dense: DenseRun | DenseCloud | None = None
                  ) -> tuple[list[CloudLayer], CameraLayer]:
    """What the 3D view of a COLMAP model shows (for :func:`prepare_view`): its points and
    a frustum per image, each with its own camera.

    Parameters
    ----------
    model : ColmapModel
        World-to-camera poses, points in the world frame.
    dense : DenseRun, DenseCloud or None, default None
        A dense cloud of the model (its world frame), thinned after the sparse points (as
        :func:`multi_view_layers`).

    Returns
    -------
    layers : list of CloudLayer
    cameras : CameraLayer
    """
    depth = frusta_depth(model.points3d, model.centers)
    corners = np.full((len(model.names), 5, 3), np.nan)
    for camera_id, camera in model.cameras.items():
        mine = np.flatnonzero(model.camera_ids == camera_id)
        if mine.size:
            corners[mine] = frustum_corners(model.R[mine], model.t[mine], camera.K,
                                            camera.image_size, depth)
    sparse = CloudLayer("points" if dense is None else "sparse", model.points3d,
                        model.colors, 2.5)
    return [sparse, *dense_clouds(dense)], CameraLayer(tuple(model.names), corners)


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
                  thumbnails: Mapping[str, bytes] | None = None,
                  dense: DenseRun | None = None) -> Html:
    """The page of a COLMAP model read from disk (``scene3d report MODEL_DIR``).

    Parameters
    ----------
    model : ColmapModel
        :func:`scene3D.io.colmap.read_colmap_text`'s model.
    source : str
        Where it was read from, as the user named it (the title).
    thumbnails : mapping of str to bytes or None, default None
        A small JPEG of each image, by name.
    dense : DenseRun or None, default None
        A dense run of the model (``scene3d dense-views``): its numbers, its depth maps
        and its cloud in the 3D view.

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
    if dense is not None:
        dense_section(page, dense)
    view_section(page, prepare_view(*colmap_layers(model, dense),
                                    meshes=dense_meshes(dense)), "Frame: the model's world "
                  "frame, shown with -y up (COLMAP's cameras look along +z with y down).")
    page.raw_json(jsonable(summary))
    return page.render(footer())
