"""HTML reports: the pieces (figure JSON, page) and the three reports of issue #23 opened in
a real headless browser (Debian's chromium through Playwright)."""

import base64
import gzip
import json
import os
import re
import subprocess
import sys

import cv2
import numpy as np
import pytest

from scene3D.calibration.uncertainty import IntrinsicsCovariance, uncertainty_map
from scene3D.densify import DepthPreview
from scene3D.io.export import atomic_write_pieces
from scene3D.report import (
    MAX_VIEW_POINTS,
    CameraLayer,
    CloudLayer,
    calibration_report,
    depth_thumbnail,
    multi_view_layers,
    multi_view_report,
    prepare_view,
    two_view_layers,
    two_view_report,
)
from scene3D.report.page import format_value, image_data_url
from scene3D.report.viewer import hex_colors_json, plotly_js_path, scene_figure_json

from .browser import changed_fraction, visit
from .conftest import REPO


def _decode(typed):
    assert typed["dtype"] == "f4"
    return np.frombuffer(base64.b64decode(typed["bdata"]), dtype="<f4")


def test_hex_colors():
    rgb = np.array([[255, 0, 16], [1, 2, 3]], dtype=np.uint8)
    assert json.loads(hex_colors_json(rgb)) == ["#ff0010", "#010203"]
    assert hex_colors_json(np.zeros((0, 3), np.uint8)) == "[]"


def test_figure_json_holds_the_points_colours_and_cameras():
    rng = np.random.default_rng(0)
    points = rng.normal(size=(500, 3)) + [0, 0, 5]
    colors = rng.integers(0, 256, (500, 3)).astype(np.uint8)
    corners = np.zeros((3, 5, 3))
    corners[1] = np.nan  # a view without a pose is skipped
    text, notes = scene_figure_json([CloudLayer("sparse", points, colors)],
                                    CameraLayer(("a", "b</script>", "c"), corners))
    assert notes == [] and "</script" not in text
    fig = json.loads(text)
    cloud, frusta, names = fig["data"]
    got = np.column_stack([_decode(cloud[k]) for k in "xyz"])
    np.testing.assert_allclose(got, points, rtol=1e-6)
    r, g, b = colors[7]
    assert cloud["marker"]["color"][7] == f"#{r:02x}{g:02x}{b:02x}"
    assert names["text"] == ["a", "c"] and frusta["name"] == "cameras (2)"
    assert fig["layout"]["scene"]["camera"]["up"] == {"x": 0, "y": -1, "z": 0}


def test_view_is_decimated_with_a_note():
    points = np.random.default_rng(1).normal(size=(1000, 3))
    sparse = CloudLayer("sparse", points[:100], None)
    dense = CloudLayer("dense", points, None)
    text, notes = scene_figure_json([sparse, dense], None, max_points=400)
    fig = json.loads(text)
    assert [len(_decode(t["x"])) for t in fig["data"]] == [100, 300]
    assert notes == ["The dense cloud shows 300 of its 1,000 points (every 3.3th: the view "
                     "holds at most 400)."]


def test_figure_json_holds_a_mesh_with_its_vertex_colours():
    from scene3D.report.viewer import MeshLayer

    vertices = np.array([[0, 0, 5], [1, 0, 5], [0, 1, 6], [1, 1, 7]], np.float64)
    faces = np.array([[0, 1, 2], [1, 3, 2]])
    colors = np.array([[255, 0, 0], [0, 255, 0], [0, 0, 255], [16, 32, 48]], np.uint8)
    text, _ = scene_figure_json([], None, meshes=(MeshLayer("mesh", vertices, faces, colors),))
    (mesh,) = json.loads(text)["data"]
    assert mesh["type"] == "mesh3d" and mesh["name"] == "mesh (2 triangles)"
    np.testing.assert_array_equal(np.column_stack([_decode(mesh[k]) for k in "xyz"]), vertices)
    ijk = np.column_stack([np.frombuffer(base64.b64decode(mesh[k]["bdata"]), "<i4")
                           for k in "ijk"])
    np.testing.assert_array_equal(ijk, faces)
    assert mesh["vertexcolor"] == ["#ff0000", "#00ff00", "#0000ff", "#102030"]


def test_page_is_self_contained_and_escapes(tmp_path):
    layers, cameras = two_view_layers(np.array([[0.0, 0, 5], [1, 1, 6]]), None, np.eye(3),
                                      np.array([-1.0, 0, 0]), np.diag([500.0, 500, 1]),
                                      (640, 480))
    summary = {"inputs": {"image1": "<b>a.jpg</b>", "image2": "b.jpg"}, "num_points": 2,
               "trusted": False, "warnings": ["few inliers"], "timings_s": {"total": 1.0}}
    png = base64.b64decode("iVBORw0KGgoAAAANSUhEUgAAAAEAAAABCAYAAAAfFcSJAAAADUlEQVR42mNk"
                           "+M9QDwADhgGAWjR9awAAAABJRU5ErkJggg==")
    html = two_view_report(summary, ["line <1>"], {"f.png": png}, prepare_view(layers, cameras))
    page = html.text()
    # Written, the page is the same text; plotly.js is in it whole, gzip-compressed.
    written = atomic_write_pieces(tmp_path / "report.html", html.encoded()).read_text("utf-8")
    assert written == page
    packed = re.search(r'id="plotly-gzip">([A-Za-z0-9+/=]+)</script>', page).group(1)
    assert gzip.decompress(base64.b64decode(packed)) == plotly_js_path().read_bytes()
    assert "<b>a.jpg" not in page and "&lt;b&gt;a.jpg" in page
    assert "Content-Security-Policy" in page and "default-src 'none'" in page
    assert "The pose may not be trustworthy" in page and "few inliers" in page
    # Outside plotly.js's own text nothing refers to another resource.
    ours = re.sub(r"<script>.*?</script>", "", page, flags=re.S)
    assert not re.search(r"(src|href)=\"(?!data:)", ours)
    assert image_data_url(png).startswith("data:image/png;base64,")
    with pytest.raises(ValueError):
        image_data_url(b"GIF89a")


def test_report_without_plotly_is_a_usage_error(tmp_path, monkeypatch, capsys):
    import importlib.util

    from scene3D.cli.chapter4 import main

    real = importlib.util.find_spec
    monkeypatch.setattr(importlib.util, "find_spec",
                        lambda name, *a: None if name == "plotly" else real(name, *a))
    assert main([str(tmp_path / "a.png"), str(tmp_path / "b.png"), "--calib",
                 str(REPO / "data" / "fountain_P11_intrinsics.yaml"),
                 "--out", str(tmp_path / "o")]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "plotly" in err and "--no-report" in err
    assert not (tmp_path / "o").exists()  # nothing written, the new folder removed


def test_multi_view_layers_skip_unregistered_views():
    R = np.stack([np.eye(3), np.eye(3), np.full((3, 3), np.nan)])
    t = np.array([[0.0, 0, 0], [-1, 0, 0], [np.nan] * 3])
    layers, cameras = multi_view_layers(("a", "b", "c"), np.diag([500.0, 500, 1]), (640, 480),
                                        [True, True, False], R, t,
                                        np.array([[0.0, 0, 5], [1, 0, 6]]), None)
    assert np.all(np.isfinite(cameras.corners[:2])) and np.all(np.isnan(cameras.corners[2]))
    np.testing.assert_allclose(cameras.corners[1, 0], [1, 0, 0])  # centre -R^T t
    page = multi_view_report(("a", "b", "c"), ["the largest model"] * 2 + [None],
                             {"points": 2, "unregistered_reasons": {"c": "no verified pair"}},
                             ["2 of 3"], ["view 'c' could not be registered: no verified pair"],
                             {}, prepare_view(layers, cameras)).text()
    assert '<div class="verdict warn" id="verdict"><strong>2 of 3 views registered' in page
    assert "<li>view &#x27;c&#x27; could not be registered: no verified pair</li>" in page
    assert "<td>c</td><td>none: no verified pair</td>" in page


def test_multi_view_views_of_further_models_are_registered():
    """Views in a further model are registered (the page said "could not be registered"
    of every view outside the largest model); the verdict is the warnings'."""
    layers, cameras = multi_view_layers(("a", "b", "c"), np.diag([500.0, 500, 1]), (640, 480),
                                        [True, True, False], np.stack([np.eye(3)] * 3),
                                        np.array([[0.0, 0, 0], [-1, 0, 0], [0, 0, 0]]),
                                        np.array([[0.0, 0, 5], [1, 0, 6]]), None)
    placed = ["the largest model", "the largest model", "model 1 (model-1/)"]
    page = multi_view_report(("a", "b", "c"), placed, {"points": 2}, ["3 of 3"], [], {},
                             prepare_view(layers, cameras)).text()
    assert ('<div class="verdict ok" id="verdict"><strong>3 of 3 views registered in 2 '
            "models</strong></div>") in page
    assert "<td>c</td><td>model 1 (model-1/)</td>" in page
    assert "<td>none: " not in page
    warned = multi_view_report(("a", "b", "c"), placed, {"points": 2}, ["3 of 3"],
                               ["focal length: known only to +-9%"], {},
                               prepare_view(layers, cameras)).text()
    assert '<div class="verdict warn"' in warned and "known only to +-9%" in warned


@pytest.mark.parametrize("value, shown", [
    (0.99998, "1.000"), (2.0, "2.000"), (1.0004, "1.000"), (0.5, "0.5000"), (0.0, "0.000"),
    (-0.31234, "-0.3123"), (100.0, "100.0"), (1234.56, "1235"), (1e-5, "1.000e-05"),
    (float("nan"), "-"), (3, "3"), (True, "yes"), (None, "-"),
])
def test_floats_keep_their_trailing_zeros(value, shown):
    """4 significant digits read as such: a ratio of 0.99998 is not shown as an exact 1."""
    assert format_value(value) == shown


def test_report_tables_show_four_digits_and_the_json_all_of_them():
    layers, cameras = two_view_layers(np.array([[0.0, 0, 5], [1, 1, 6]]), None, np.eye(3),
                                      np.array([-1.0, 0, 0]), np.diag([500.0, 500, 1]),
                                      (640, 480))
    summary = {"focal_scale": 0.99998, "median_parallax_deg": 2.0, "trusted": True}
    page = two_view_report(summary, [], {}, prepare_view(layers, cameras)).text()
    tables = page.split("<details>")[0]
    # In words with its unit and explanation, formatted as the summary lines format it.
    assert ("<td>focal length the matches call for<div class=\"explain\">1.000 when the "
            "calibration&#x27;s focal length fits these photos</div></td><td class=num>1.000 "
            "x the calibration&#x27;s</td>") in tables
    assert "<td>median parallax<div class=\"explain\">" in tables
    assert "<td class=num>2.00 deg</td>" in tables
    assert "focal_scale" not in tables and "median_parallax_deg" not in tables
    assert "&quot;focal_scale&quot;: 0.99998," in page.split("<details>")[1]  # in full


def test_multi_view_models_are_a_table_of_their_own():
    """The summary's ``models`` (a list of dicts, ground-truth arrays among their fields)
    is a table of their counts and errors in words, not a Python repr in one cell."""
    layers, cameras = multi_view_layers(("a", "b"), np.diag([500.0, 500, 1]), (640, 480),
                                        [True, True], np.stack([np.eye(3)] * 2),
                                        np.array([[0.0, 0, 0], [-1, 0, 0]]),
                                        np.array([[0.0, 0, 5], [1, 0, 6]]), None)
    models = [{"folder": ".", "status": "ok", "registered": 2, "points": 2,
               "mean_track_length": 2.0, "reprojection_rmse_px": 0.12345,
               "center_error_fraction_of_extent": np.array([1e-3, 2e-3])},
              {"folder": "model-1", "status": "failed", "registered": 1, "points": 0,
               "mean_track_length": 0.0, "reprojection_rmse_px": float("nan")}]
    page = multi_view_report(("a", "b"), ["the largest model"] * 2,
                             {"points": 2, "models": models}, ["2 of 2"], [], {},
                             prepare_view(layers, cameras)).text()
    assert ("<table id=\"models\"><tr><th>model</th><th>status</th><th>views registered</th>"
            "<th>3D points</th><th>mean track length</th><th>reprojection error (RMS)</th>"
            "</tr><tr><td>the largest (this folder)</td><td>ok</td><td>2</td><td>2</td>"
            "<td>2.00</td><td>0.123 px</td></tr><tr><td>model 1 (model-1/)</td>"
            "<td>failed</td><td>1</td><td>0</td><td>0.00</td><td>-</td></tr></table>") in page
    assert "{&#x27;" not in page and "array(" not in page.split("<details>")[0]


def test_the_view_graph_of_many_views_groups_consecutive_views():
    """Five views at most two rows: groups of three (the last of two), each cell the sum of
    its pairs' shared points; few views are left as they are."""
    from scene3D.report.diagnostics import grouped_view_graph

    names = ["a", "b", "c", "d", "e"]
    shared = np.arange(25).reshape(5, 5)
    shared = shared + shared.T
    labels, matrix, group = grouped_view_graph(names, shared, max_views=2)
    assert labels == ["a - c", "d - e"] and group == 3
    np.testing.assert_array_equal(matrix, [[shared[:3, :3].sum(), shared[:3, 3:].sum()],
                                           [shared[3:, :3].sum(), shared[3:, 3:].sum()]])
    labels, matrix, group = grouped_view_graph(names, shared, max_views=5)
    assert labels == names and group == 1
    np.testing.assert_array_equal(matrix, shared)
    assert grouped_view_graph(names, shared, max_views=4)[0] == ["a - b", "c - d", "e"]
    with pytest.raises(ValueError, match="max_views must be at least 1"):
        grouped_view_graph(names, shared, max_views=0)


def test_a_report_of_many_views_bounds_its_thumbnails_and_graph():
    """250 views: thumbnails of 100 of them, evenly spaced with the first and the last, and
    the page says so; the view graph has at most MAX_GRAPH_VIEWS rows and says how it
    groups."""
    from scene3D.cli.report import thumbnails
    from scene3D.report import ViewDiagnostics
    from scene3D.report.diagnostics import MAX_GRAPH_VIEWS

    V = 250
    names = [f"{v:03d}.png" for v in range(V)]
    frames = [np.full((16, 24, 3), v, np.uint8) for v in range(V)]
    thumbs = thumbnails(frames, names, limit=100)
    assert len(thumbs) == 100 and {"000.png", "249.png"} <= set(thumbs)
    gaps = np.diff(sorted(int(n[:3]) for n in thumbs))
    assert gaps.min() >= 2 and gaps.max() <= 3
    shared = np.zeros((V, V), np.int64)
    for v in range(V - 1):
        shared[v, v + 1] = shared[v + 1, v] = 10
    d = ViewDiagnostics(tuple(names), np.full(V, 20), np.full(V, 0.2), np.full(5, 2),
                        np.full(10, 0.1), shared)
    R = np.stack([np.eye(3)] * V)
    t = np.stack([[-0.1 * v, 0, 0] for v in range(V)])
    layers, cameras = multi_view_layers(names, np.diag([500.0, 500, 1]), (24, 16),
                                        [True] * V, R, t, np.array([[0.0, 0, 5]]), None)
    page = multi_view_report(names, ["the largest model"] * V, {"points": 1}, [], [], {},
                             prepare_view(layers, cameras), diagnostics=d,
                             thumbnails=thumbs).text()
    assert "Thumbnails of 100 of the 250 views, evenly spaced" in page
    assert page.count('class="thumb"') == 100
    group = -(-V // MAX_GRAPH_VIEWS)
    assert f"The 250 views are grouped {group} at a time" in page
    assert "000.png - 002.png and 003.png - 005.png: 10 points" in page


# -- in the browser -----------------------------------------------------------------------

def _run(args, cwd, timeout=600):
    env = dict(os.environ, MPLBACKEND="Agg")
    proc = subprocess.run([sys.executable, *map(str, args)], cwd=cwd, env=env,
                          capture_output=True, text=True, timeout=timeout)
    assert proc.returncode == 0, proc.stderr
    return proc


def _check_page(visit_result, with_view, images):
    assert visit_result.errors == [], visit_result.errors
    assert visit_result.requests and visit_result.outside_requests == [], visit_result.requests
    assert visit_result.images == images and visit_result.broken_images == 0
    if with_view:
        # The clouds cover part of the WebGL canvas (hiding them changes those pixels) and
        # a drag turns the scene.
        assert changed_fraction(visit_result.canvas_after_drag,
                                visit_result.canvas_without_clouds) > 0.003
        assert "scene.camera" in visit_result.relayout_keys
        assert changed_fraction(visit_result.canvas_pixels,
                                visit_result.canvas_after_drag) > 0.003


# A file name (optic_flow.png, fountain_P11_intrinsics.yaml) is not a field name.
_FILE_NAME = re.compile(r"[\w./-]+\.(png|jpe?g|yaml|yml|json|ply|txt|html|camera)\b")
_SNAKE = re.compile(r"\b[a-z][a-z0-9]*(?:_[a-z0-9]+)+\b")


def _keys(obj):
    """Every key of a JSON document, nested ones too."""
    if isinstance(obj, dict):
        for k, v in obj.items():
            yield k
            yield from _keys(v)
    elif isinstance(obj, list):
        for v in obj:
            yield from _keys(v)


def _assert_no_field_names(text, document=None):
    """The visible text has no internal name: no snake_case word outside file names, and
    none of the JSON's keys with an underscore (the collapsed JSON block is not visible)."""
    words = _FILE_NAME.sub(" ", text)
    assert _SNAKE.findall(words) == [], _SNAKE.findall(words)
    if document is not None:
        shown = [k for k in set(_keys(document)) if "_" in k and re.search(
            rf"\b{re.escape(k)}\b", words)]
        assert shown == [], shown


def _row_value(text, label):
    """The value column of the quantity row ``label`` in the visible text (the row reads
    "label / explanation / value" in innerText)."""
    match = re.search(rf"^{re.escape(label)}\n(?:[^\n]*\n)?\t([^\n]+)$", text, re.M)
    assert match, f"no row {label!r}"
    return match.group(1).strip()


def test_book_pair_report_in_browser(tmp_path, data_root):
    out = tmp_path / "out"
    _run([REPO / "chapter4.py", "--out", out], tmp_path)
    summary = json.loads((out / "reconstruction.json").read_text())
    page = visit(out / "report.html", wait_for_view=True)
    _check_page(page, with_view=True, images=4)
    text = page.text
    line = (f"{summary['num_matches']} matches, {summary['num_inliers']} inliers, "
            f"{summary['num_points']} points, reprojection RMSE "
            f"{summary['reprojection_rmse_px']:.3f} px")
    assert line in text
    # The verdict first, then the command's lines.
    assert text.index("Trusted result") < text.index(line)
    assert f"{summary['num_points']:,} points (plotly.js" in text
    assert '"name":"cameras (2)"' in (out / "report.html").read_text()
    _assert_no_field_names(text, summary)
    # Numbers in words, with units, formatted as the summary line formats them.
    assert _row_value(text, "reprojection error (RMS)") == \
        f"{summary['reprojection_rmse_px']:.3f} px"
    assert _row_value(text, "rotation uncertainty (1 sigma)") == \
        f"{summary['rotation_sigma_deg']:.3f} deg"
    assert _row_value(text, "matches a plane explains") == \
        f"{100 * summary['homography_inlier_ratio']:.1f} %"
    # R, t and K shown plainly, and the title names the photos, not their paths.
    for value in (*np.ravel(summary["R"]), *summary["t"]):
        assert f"{value:.4f}" in text
    assert f"{summary['K'][0][0]:.2f}" in text and "Camera model: pinhole" in text
    assert text.startswith("scene3D reconstruction: 0004.jpg + 0005.jpg")


def test_fountain_eleven_views_report_in_browser(tmp_path, fountain):
    out = tmp_path / "views"
    _run(["-m", "scene3D", "reconstruct-views", fountain / "images", "--calib",
          REPO / "data" / "fountain_P11_intrinsics.yaml", "--ground-truth",
          fountain / "gt_dense_cameras", "--out", out], tmp_path, timeout=900)
    summary = json.loads((out / "reconstruction.json").read_text())
    page = visit(out / "report.html", wait_for_view=True)
    _check_page(page, with_view=True, images=1 + 11)  # cameras.png, a thumbnail a view
    text = page.text
    assert f"{summary['registered']} of 11 views registered" in text
    assert f"{summary['points']:,} points (plotly.js" in text
    assert f"reprojection RMSE {summary['reprojection_rmse_px']:.3f} px" in text
    html = (out / "report.html").read_text()
    assert f'"name":"cameras ({summary["registered"]})"' in html
    _assert_no_field_names(text, summary)
    gt = summary["ground_truth"]
    assert _row_value(text, "camera centre error, worst") == \
        f"{100 * gt['max_center_error_fraction']:.3f} %"
    assert f"camera centres within {100 * gt['max_center_error_fraction']:.3f} %" in text
    assert _row_value(text, "mean track length") == f"{summary['mean_track_length']:.2f}"
    # The views table: a row per view with the points it sees, its reprojection error and
    # its ground-truth errors. Its observations add up to points x mean track length, and
    # its errors combine (weighted by the points seen) to the model's RMS error.
    rows = re.findall(r"^\t?(\d{4}\.jpg)\tthe largest model\t(\d+)\t([0-9.]+) px\t"
                      r"([0-9.]+) %\t([0-9.]+) deg$", text, re.M)
    assert [r[0] for r in rows] == gt["views"]
    seen = np.array([int(r[1]) for r in rows])
    rmse = np.array([float(r[2]) for r in rows])
    assert seen.sum() == round(summary["points"] * summary["mean_track_length"])
    combined = np.sqrt(np.sum(seen * rmse ** 2) / seen.sum())
    assert abs(combined - summary["reprojection_rmse_px"]) < 0.0006  # the rounding of .3f
    for r, centre, rotation in zip(rows, gt["center_error_fraction_of_extent"],
                                   gt["rotation_error_deg"]):
        assert r[3] == f"{100 * centre:.3f}" and r[4] == f"{rotation:.3f}"
    # Both histograms and the view graph: the track lengths count every point once, and
    # two views share a point at most as often as the one that sees fewer.
    tracks = re.search(r'aria-label="views that see the point">(.*?)</svg>', html).group(1)
    counts = [int(c) for c in re.findall(r"<title>\d+\+?: (\d+)</title>", tracks)]
    assert sum(counts) == summary["points"]
    assert 'aria-label="reprojection error (px)"' in html
    assert "Track length: how many views see each 3D point." in text
    shared = re.findall(r"<title>(\d{4}\.jpg) and (\d{4}\.jpg): (\d+) points</title>", html)
    by_name = dict(zip(gt["views"], seen))
    assert len(shared) > 50
    assert all(int(n) <= min(by_name[a], by_name[b]) for a, b, n in shared)


def test_colmap_model_report_in_browser(tmp_path, fountain):
    """``scene3d report MODEL_DIR`` on the COLMAP model reconstruct-views wrote: the
    page opens with its 3D view and thumbnails, and its numbers are the model's (the
    COLMAP files are at the photos' size, twice the working size: errors twice as large)."""
    out = tmp_path / "views"
    _run(["-m", "scene3D", "reconstruct-views", fountain / "images", "--calib",
          REPO / "data" / "fountain_P11_intrinsics.yaml", "--out", out, "--no-report",
          "--no-plots"], tmp_path, timeout=900)
    summary = json.loads((out / "reconstruction.json").read_text())
    proc = _run(["-m", "scene3D", "report", "views/colmap", "--images", fountain / "images"],
                tmp_path)
    assert proc.stdout.splitlines() == [f"11 images, {summary['points']} points, 1 camera",
                                        "Wrote 'views/colmap/report.html'"]
    page = visit(out / "colmap" / "report.html", wait_for_view=True)
    _check_page(page, with_view=True, images=11)
    text = page.text
    _assert_no_field_names(text)
    assert text.startswith("scene3D report of the COLMAP model views/colmap")
    assert _row_value(text, "3D points") == str(summary["points"])
    assert _row_value(text, "mean track length") == f"{summary['mean_track_length']:.2f}"
    rmse = float(_row_value(text, "reprojection error (RMS)").removesuffix(" px"))
    assert abs(rmse - 2 * summary["reprojection_rmse_px"]) < 0.002
    assert "pinhole: no lens distortion (PINHOLE)" in text and "3072 x 2048 px" in text
    # Again: an existing page is refused (exit code 2) unless --force.
    again = subprocess.run([sys.executable, "-m", "scene3D", "report", "views/colmap"],
                           cwd=tmp_path, capture_output=True, text=True)
    assert again.returncode == 2
    assert again.stderr.strip() == ("error: 'views/colmap/report.html' exists (--force "
                                    "replaces it)")


def test_report_of_a_folder_without_a_model_is_a_usage_error(tmp_path, capsys):
    from scene3D.cli.report import main

    assert main([str(tmp_path)]) == 2
    err = capsys.readouterr().err.strip()
    assert err.startswith("error: ") and "cameras.txt" in err and "\n" not in err


def test_left_calibration_report_in_browser(tmp_path, chessboards):
    out = tmp_path / "left.yaml"
    proc = _run([REPO / "calibrate.py", "--images", chessboards / "opencv-left", "--out", out],
                tmp_path)
    page = visit(tmp_path / "left_report.html", wait_for_view=False)
    _check_page(page, with_view=False, images=3)
    rms = re.search(r"RMS reprojection error: ([0-9.]+) px", proc.stdout).group(1)
    median = re.search(r"projection uncertainty \(1 sigma\): median ([0-9.]+) px",
                       proc.stdout).group(1)
    assert f"RMS reprojection error: {rms} px" in page.text
    assert f"median {median} px" in page.text
    assert "exceeds 1 px" in page.text  # the boards never reach the corners
    assert (tmp_path / "left_uncertainty.png").read_bytes().startswith(b"\x89PNG")
    _assert_no_field_names(page.text)
    assert "focal length along x, in pixels" in page.text
    assert page.text.index("Warnings") < page.text.index("RMS reprojection error: ")


def test_calibration_report_lists_views_and_uncertainty():
    names = ("fx", "fy", "cx", "cy", "k1", "k2", "p1", "p2", "k3")
    cov = np.diag([1.0, 1.0, 0.25, 0.25] + [0.0] * 5)
    umap = uncertainty_map(np.diag([500.0, 500, 1]) + [[0, 0, 320], [0, 0, 240], [0, 0, 0]],
                           np.zeros(5), IntrinsicsCovariance(names, cov, 0.2, 100), (640, 480))
    page = calibration_report(["RMS 0.2"], {"fx (px)": "500 +- 1"}, {"a.jpg": 0.2},
                              {"b.jpg": 3.0}, umap.warnings, umap, {}).text()
    assert "dropped as an outlier" in page and "b.jpg" in page
    assert format_value(umap.median_px) in page


def test_compressed_plotly_is_kept_in_the_cache(tmp_path, monkeypatch):
    """Compressed once: the cache's file is what later pages copy; an unwritable cache
    gives the text itself."""
    from scene3D.report.viewer import compressed_plotly_js

    monkeypatch.setenv("SCENE3D_CACHE", str(tmp_path / "cache"))
    first = compressed_plotly_js(plotly_js_path())
    assert first.parent == tmp_path / "cache" and first.suffix == ".b64"
    assert gzip.decompress(base64.b64decode(first.read_text())) == \
        plotly_js_path().read_bytes()
    mtime = first.stat().st_mtime_ns
    assert compressed_plotly_js(plotly_js_path()) == first
    assert first.stat().st_mtime_ns == mtime  # read again, not rewritten
    (tmp_path / "file").write_text("")
    monkeypatch.setenv("SCENE3D_CACHE", str(tmp_path / "file" / "cache"))  # not a folder
    assert compressed_plotly_js(plotly_js_path()) == first.read_text()


# -- the dense view (issue #53) ------------------------------------------------------------

def test_depth_thumbnail_is_red_near_blue_far_and_grey_without_depth():
    depth = np.tile(np.linspace(1.0, 10.0, 40, dtype=np.float32), (30, 1))
    depth[:, 18:22] = np.nan
    jpg = depth_thumbnail(DepthPreview(depth, (400, 300), 1))
    image = cv2.imdecode(np.frombuffer(jpg, np.uint8), cv2.IMREAD_COLOR).astype(int)
    assert image.shape == (30, 40, 3)
    near, far, hole = image[15, 1], image[15, 38], image[15, 20]
    assert near[2] > 120 and near[2] > near[0] + 80  # BGR: red (turbo ends in dark red)
    assert far[0] > 80 and far[0] > far[2] + 40  # blue
    assert np.all(np.abs(hole - 225) < 12)  # light grey


def _figure(html):
    """The 3D view's figure, read back from the page."""
    text = re.search(r'<script type="application/json" id="view3d-data">(.*?)</script>',
                     html, re.S).group(1)
    return json.loads(text)


def _check_dense_page(out, dense_summary, names, thumbnails):
    """The page in ``out`` opens without an error, with a dense trace of at most the
    view's bound (the sparse points whole, the dense ones thinned to the rest), a depth
    thumbnail per view that decodes, and no internal name in its text."""
    page = visit(out / "report.html", wait_for_view=True)
    _check_page(page, with_view=True, images=thumbnails + len(names))
    html = (out / "report.html").read_text()
    traces = {t["name"].split(" (")[0]: t for t in _figure(html)["data"]}
    sparse, dense = len(_decode(traces["sparse"]["x"])), len(_decode(traces["dense"]["x"]))
    assert dense == min(dense_summary["points"], MAX_VIEW_POINTS - sparse)
    assert traces["dense"]["name"] == f"dense ({dense:,})"
    assert len(traces["dense"]["marker"]["color"]) == dense
    text = page.text
    assert _row_value(text, "dense points") == f"{dense_summary['points']:,}"
    assert f"The 3D view holds at most {MAX_VIEW_POINTS:,} points" in text
    if dense < dense_summary["points"]:
        assert (f"The dense cloud shows {dense:,} of its {dense_summary['points']:,} "
                "points") in text
    for name, view in zip(names, dense_summary["views"]):
        jpg = re.search(rf'<img src="data:image/jpeg;base64,([^"]+)" alt="depth map of '
                        rf'{re.escape(name)}"', html)
        image = cv2.imdecode(np.frombuffer(base64.b64decode(jpg.group(1)), np.uint8),
                             cv2.IMREAD_COLOR)
        assert image.shape[1] == 160 and image.std() > 10  # coloured, not blank
        width, height = dense_summary["image_size"]
        share = view["depth_pixels"] / (width * height)
        assert f"{name}: depth at {share:.0%} of the pixels" in text
    return text, html


def test_dense_views_report_in_browser(tmp_path):
    """``scene3d dense-views`` on five rendered views writes report.html beside the cloud:
    the model's page with the dense cloud in its 3D view and the depth maps."""
    from scene3D.evaluation.dense import render_orbit_views

    from .test_densify import _write_scene

    model = _write_scene(tmp_path / "scene", render_orbit_views(5, size=(200, 150),
                                                                 arc_deg=40.0))
    out = tmp_path / "dense"
    proc = _run(["-m", "scene3D", "dense-views", model, "--images", model.parent, "--out",
                 out, "--no-pyr-down"], tmp_path)
    assert f"Wrote '{out / 'report.html'}'" in proc.stdout
    summary = json.loads((out / "dense.json").read_text())
    summary["image_size"] = [200, 150]
    names = [f"view{k:02d}.png" for k in range(5)]
    text, _ = _check_dense_page(out, summary, names, thumbnails=5)
    _assert_no_field_names(text, summary)
    assert text.startswith("scene3D report of the COLMAP model")
    assert _row_value(text, "depth maps") == "5 of 5"


def test_dense_views_mesh_report_in_browser(tmp_path):
    """With --mesh the 3D view shows the mesh (at most MAX_VIEW_FACES triangles) instead of
    the dense cloud, and the page says so."""
    pytest.importorskip("open3d")
    from scene3D.evaluation.dense import render_orbit_views
    from scene3D.report.dense import MAX_VIEW_FACES

    from .test_densify import _write_scene

    model = _write_scene(tmp_path / "scene", render_orbit_views(5, size=(200, 150),
                                                                 arc_deg=40.0))
    out = tmp_path / "dense"
    _run(["-m", "scene3D", "dense-views", model, "--images", model.parent, "--out", out,
          "--no-pyr-down", "--mesh"], tmp_path)
    summary = json.loads((out / "dense.json").read_text())
    page = visit(out / "report.html", wait_for_view=True)
    _check_page(page, with_view=True, images=5 + 5)
    _assert_no_field_names(page.text, summary)
    traces = {t["name"].split(" (")[0]: t for t in
              _figure((out / "report.html").read_text())["data"]}
    assert "dense" not in traces and traces["mesh"]["type"] == "mesh3d"
    faces = len(np.frombuffer(base64.b64decode(traces["mesh"]["i"]["bdata"]), "<i4"))
    total = summary["mesh"]["faces"]
    assert faces == total if total <= MAX_VIEW_FACES else 0.5 * MAX_VIEW_FACES < faces <= \
        MAX_VIEW_FACES
    assert (f"with {faces:,} of its {summary['mesh']['faces']:,} triangles (at most "
            f"{MAX_VIEW_FACES:,}") in page.text
    assert _row_value(page.text, "mesh triangles") == f"{summary['mesh']['faces']:,}"


def test_reconstruct_views_dense_report_in_browser(tmp_path, fountain):
    """``reconstruct-views --dense`` on three fountain photos: its report shows the dense
    cloud (712,280 points on 2026-12-08: thinned to the view's bound) and the depth maps."""
    photos = tmp_path / "photos"
    photos.mkdir()
    for i in (4, 5, 6):
        (photos / f"{i:04d}.jpg").symlink_to(fountain / "images" / f"{i:04d}.jpg")
    out = tmp_path / "out"
    _run(["-m", "scene3D", "reconstruct-views", photos, "--calib",
          REPO / "data" / "fountain_P11_intrinsics.yaml", "--max-width", "640", "--no-plots",
          "--dense", "--out", out], tmp_path, timeout=1200)  # the dense stage at 1536 px
    summary = json.loads((out / "reconstruction.json").read_text())
    dense = json.loads((out / "dense" / "dense.json").read_text())
    dense["image_size"] = [1536, 1024]  # the dense stage's own size (DenseSettings)
    names = [v["name"] for v in dense["views"]]
    text, html = _check_dense_page(out, dense, names, thumbnails=3)
    _assert_no_field_names(text, summary)
    _assert_no_field_names(text, dense)
    assert text.index("Dense cloud") < text.index("3D view")
