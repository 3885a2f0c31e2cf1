"""The interactive 3D view of a report: a plotly.js figure built as JSON, no plotly Python.

plotly.js comes from the installed ``plotly`` package (its bundled ``plotly.min.js``,
4.8 MB), inlined gzip-compressed and base64-encoded (2.0 MB, :func:`compressed_plotly_js`,
kept in the user cache):
the browser unpacks it with its built-in ``DecompressionStream``, so the report needs no
network; the package's Python modules are never imported (the figure is plain JSON, built
here in a few milliseconds).
Point coordinates travel as base64 float32 typed arrays (plotly.js's ``{dtype, bdata}``
form), colours as ``#rrggbb`` strings.

The view reads results; the camera frusta come from :func:`scene3D.viz.drawing.frustum_corners`.
Frames: points and cameras in the reconstruction's frame (a camera frame: ``x`` right,
``y`` down, ``z`` forward); the view is set up with ``-y`` up.
"""

from __future__ import annotations

import base64
import functools
import gzip
import importlib.util
import json
import os
import re
import tempfile
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..geometry.conventions import FloatArray
from ..viz.drawing import robust_extent, subsample_indices

#: At most this many points are sent to the browser, all layers together; beyond it a
#: random subset is shown (with a note) so that the view stays responsive.
MAX_VIEW_POINTS = 300_000


class MissingViewerError(RuntimeError):
    """plotly.js (the ``plotly`` package) is not installed.

    Attributes
    ----------
    reason : str
        ``"no_plotly"`` (the package is missing) or ``"no_plotly_js"`` (it has no
        ``plotly.min.js``).
    """

    def __init__(self, message: str, reason: str = "no_plotly") -> None:
        self.reason = reason
        super().__init__(message)

    def __reduce__(self) -> tuple:
        return type(self), (self.args[0], self.reason)


@dataclass(frozen=True)
class CloudLayer:
    """One point cloud of the view.

    Attributes
    ----------
    name : str
        Legend entry ("sparse", "dense").
    points3d : (N, 3) float64
    colors : (N, 3) uint8 or None
        RGB.
    marker_size : float
        Marker diameter in screen pixels.
    """

    name: str
    points3d: FloatArray
    colors: np.ndarray | None
    marker_size: float = 2.0


@dataclass(frozen=True)
class MeshLayer:
    """A triangle mesh of the view (plotly.js ``mesh3d``), shown as it is: a large mesh is
    simplified before (:func:`scene3D.densify.mesh.simplify_mesh`).

    Attributes
    ----------
    name : str
        Legend entry.
    vertices : (V, 3) float64
    faces : (F, 3) int
        Vertex indices of each triangle.
    colors : (V, 3) uint8
        RGB of each vertex.
    """

    name: str
    vertices: FloatArray
    faces: np.ndarray
    colors: np.ndarray


@dataclass(frozen=True)
class CameraLayer:
    """Camera frusta: ``corners[v] = (centre, 4 image corners)`` in the view's frame.

    Attributes
    ----------
    names : tuple[str, ...]
    corners : (V, 5, 3) float64
        From :func:`scene3D.viz.drawing.frustum_corners`; rows with NaN are skipped.
    """

    names: tuple[str, ...]
    corners: FloatArray


@dataclass(frozen=True)
class PreparedView:
    """Everything the page needs for the 3D view (built before the page, so that a command
    can build it while its figures are being encoded).

    Attributes
    ----------
    plotly_js : Path
        The library's file (``plotly.min.js``), to inline.
    version : str
        plotly.js version.
    figure_json : str
        The figure (:func:`scene_figure_json`).
    notes : list of str
        Notes for the reader (decimation).
    num_points : int
        Points of all layers before decimation.
    """

    plotly_js: Path
    version: str
    figure_json: str
    notes: list[str]
    num_points: int


def prepare_view(layers: list[CloudLayer], cameras: CameraLayer | None = None,
                 max_points: int = MAX_VIEW_POINTS,
                 meshes: tuple[MeshLayer, ...] = ()) -> PreparedView:
    """plotly.js and the figure JSON of ``layers`` and ``cameras``.

    Parameters
    ----------
    layers : list of CloudLayer
        Point clouds to show.
    cameras : CameraLayer or None, default None
        Cameras to draw.
    max_points : int, default MAX_VIEW_POINTS
        Most points shown over all layers (decimated beyond).
    meshes : tuple of MeshLayer, default ()
        Surfaces to show.

    Returns
    -------
    PreparedView
    """
    js, version = plotly_js()
    figure_json, notes = scene_figure_json(layers, cameras, max_points, meshes)
    return PreparedView(js, version, figure_json, notes,
                        sum(len(layer.points3d) for layer in layers))


def plotly_js_path() -> Path:
    """Location of the installed ``plotly`` package's ``plotly.min.js`` (the package is
    located, not imported)."""
    spec = importlib.util.find_spec("plotly")
    if spec is None or not spec.submodule_search_locations:
        raise MissingViewerError("the report's 3D view needs the 'plotly' package "
                                 "(pip install plotly)", "no_plotly")
    path = Path(list(spec.submodule_search_locations)[0]) / "package_data" / "plotly.min.js"
    if not path.is_file():
        raise MissingViewerError(f"the 'plotly' package has no '{path.name}' at '{path}'",
                                 "no_plotly_js")
    return path


def plotly_js() -> tuple[Path, str]:
    """The path of ``plotly.min.js`` and its version (e.g. ``"4.1.1"``, from the file's
    banner)."""
    path = plotly_js_path()
    with open(path, "rb") as f:
        head = f.read(400).decode("utf-8", errors="replace")
    match = re.search(r"plotly\.js v(\d+\.\d+\.\d+)", head)
    return path, match.group(1) if match else "unknown"


def compressed_plotly_js(path: Path) -> str | Path:
    """The file ``path`` (``plotly.min.js``) gzip-compressed, as base64 text.

    Browsers unpack it with ``DecompressionStream("gzip")`` (Chrome 80, Firefox 113,
    Safari 16.4). Compressing plotly.js takes about 0.2 s, so the text is kept in the user
    cache (``$SCENE3D_CACHE``, ``$XDG_CACHE_HOME/scene3D`` or ``~/.cache/scene3D``), under
    a name with the file's size and time: a page then copies it from there
    (:class:`scene3D.report.page.Html`). Where the cache cannot be written, the text is
    made once per process.

    Parameters
    ----------
    path : Path
        The script.

    Returns
    -------
    str or Path
        The ASCII base64 text of the gzip stream (a third of plotly.js's size), or the
        cached file that holds it.
    """
    from ..io.datasets import default_cache_dir

    stat = path.stat()
    cached = default_cache_dir() / f"{path.stem}-{stat.st_size}-{stat.st_mtime_ns}.gz.b64"
    if cached.is_file():
        return cached
    text = _compressed(str(path), stat.st_size, stat.st_mtime_ns)
    try:
        cached.parent.mkdir(parents=True, exist_ok=True)
        with tempfile.NamedTemporaryFile("w", encoding="ascii", dir=cached.parent,
                                         suffix=".tmp", delete=False) as f:
            f.write(text)
        os.replace(f.name, cached)  # whole or absent: a concurrent run reads either
    except OSError:
        return text
    return cached


@functools.lru_cache(maxsize=2)
def _compressed(path: str, size: int, mtime_ns: int) -> str:
    # size and mtime key the cache: a reinstalled plotly is compressed again.
    data = Path(path).read_bytes()
    return base64.b64encode(gzip.compress(data, compresslevel=9, mtime=0)).decode("ascii")


def _typed(values: np.ndarray, dtype: str = "f4") -> dict:
    """plotly.js typed array: little-endian float32 (or ``"i4"``, int32), base64."""
    data = np.ascontiguousarray(values, dtype="<" + dtype)
    return {"dtype": dtype, "bdata": base64.b64encode(data.tobytes()).decode("ascii")}


_HEX = np.frombuffer(b"0123456789abcdef", dtype=np.uint8)


def hex_colors_json(rgb: np.ndarray) -> str:
    """A JSON array of ``"#rrggbb"`` strings for ``(N, 3) uint8`` colours, built in numpy.

    Parameters
    ----------
    rgb : (N, 3) uint8 array_like
        RGB colours.

    Returns
    -------
    str
    """
    rgb = np.asarray(rgb, dtype=np.uint8).reshape(-1, 3)
    if len(rgb) == 0:
        return "[]"
    text = np.empty((len(rgb), 11), dtype=np.uint8)
    text[:, 0], text[:, 1] = ord('"'), ord("#")
    for c in range(3):
        text[:, 2 + 2 * c] = _HEX[rgb[:, c] >> 4]
        text[:, 3 + 2 * c] = _HEX[rgb[:, c] & 15]
    text[:, 8], text[:, 9], text[:, 10] = ord('"'), ord(","), ord(" ")
    return "[" + text.tobytes()[:-2].decode("ascii") + "]"


def _decimate(layers: list[CloudLayer], max_points: int
              ) -> tuple[list[tuple[CloudLayer, np.ndarray]], list[str]]:
    """Each layer with the indices shown; the layers listed first are kept whole first."""
    left, kept, notes = max_points, [], []
    for layer in layers:
        n = len(layer.points3d)
        idx = subsample_indices(n, max(left, 0))
        if len(idx) < n:
            notes.append(f"The {layer.name} cloud shows {len(idx):,} of its {n:,} points "
                         f"(every {n / max(len(idx), 1):.1f}th: the view holds at most "
                         f"{max_points:,}).")
        left -= len(idx)
        kept.append((layer, idx))
    return kept, notes


def dense_box(points3d: np.ndarray, share: float = 0.7, margin: float = 0.35
              ) -> tuple[FloatArray, FloatArray]:
    """Lower and upper corners ``(3,), (3,)`` of the box around the densest part of a cloud:
    on each axis the shortest interval holding ``share`` of the points, widened by
    ``margin`` of its length on each side (never beyond the 2nd-98th percentile box).

    A far, sparse part of the cloud (a background wall, a few stray points) then lies
    outside the view's first frame instead of shrinking the scene to a corner of it.

    Parameters
    ----------
    points3d : (N, 3) array_like
        Points.
    share : float, default 0.7
        The part of the points the interval holds, per axis.
    margin : float, default 0.35
        Widening on each side, as a fraction of the interval's length.

    Returns
    -------
    low, high : (3,) float64 ndarray
        The unit box for no points.
    """
    points3d = np.asarray(points3d, dtype=np.float64).reshape(-1, 3)
    n = len(points3d)
    if n == 0:
        return np.zeros(3), np.ones(3)
    outer_lo, outer_hi = robust_extent(points3d)
    w = max(int(np.ceil(share * n)), 1)
    s = np.sort(points3d, axis=0)
    widths = s[w - 1:] - s[:n - w + 1]  # (n - w + 1, 3): every window of w points
    start = np.argmin(widths, axis=0)
    lo, hi = s[start, np.arange(3)], s[start + w - 1, np.arange(3)]
    pad = margin * (hi - lo)
    return np.maximum(lo - pad, outer_lo), np.minimum(hi + pad, outer_hi)


def _label_positions(centres: np.ndarray, min_gap: float) -> list[int]:
    """Indices of the cameras to label: greedily, each at least ``min_gap`` from those
    already labelled, so that names do not print over each other (all show on hover)."""
    kept: list[int] = []
    for i, c in enumerate(centres):
        if all(np.linalg.norm(c - centres[j]) >= min_gap for j in kept):
            kept.append(i)
    return kept


def scene_figure_json(layers: list[CloudLayer], cameras: CameraLayer | None = None,
                      max_points: int = MAX_VIEW_POINTS,
                      meshes: tuple[MeshLayer, ...] = ()) -> tuple[str, list[str]]:
    """The plotly.js figure (``{"data": ..., "layout": ...}``) as JSON text, and notes.

    Parameters
    ----------
    layers : list of CloudLayer
        Point clouds to show.
    cameras : CameraLayer or None, default None
        Cameras to draw.
    max_points : int, default MAX_VIEW_POINTS
        Most points shown over all layers.
    meshes : tuple of MeshLayer, default ()
        Surfaces to show (after the clouds in the legend; their vertices count for the
        box the view opens on).

    Returns
    -------
    json_text : str
        Safe to embed in a ``<script type="application/json">`` element.
    notes : list of str
        What the reader should know about the view (e.g. that a cloud was decimated).
    """
    kept, notes = _decimate(layers, max_points)
    data: list[dict] = []
    colors: dict[str, str] = {}
    shown = []
    for k, (layer, idx) in enumerate(kept):
        pts = np.asarray(layer.points3d, dtype=np.float64).reshape(-1, 3)[idx]
        shown.append(pts)
        marker: dict = {"size": layer.marker_size, "opacity": 1.0}
        if layer.colors is not None:
            placeholder = f"@@colors{k}@@"
            colors[placeholder] = hex_colors_json(np.asarray(layer.colors)[idx])
            marker["color"] = placeholder
        data.append({
            "type": "scatter3d", "mode": "markers", "name": f"{layer.name} ({len(idx):,})",
            "x": _typed(pts[:, 0]), "y": _typed(pts[:, 1]), "z": _typed(pts[:, 2]),
            "marker": marker, "hoverinfo": "skip" if len(idx) > 20000 else "x+y+z+name",
        })
    for k, mesh in enumerate(meshes):
        vertices = np.asarray(mesh.vertices, dtype=np.float64).reshape(-1, 3)
        faces = np.asarray(mesh.faces).reshape(-1, 3)
        shown.append(vertices)
        placeholder = f"@@meshcolors{k}@@"
        colors[placeholder] = hex_colors_json(np.asarray(mesh.colors))
        data.append({
            "type": "mesh3d", "name": f"{mesh.name} ({len(faces):,} triangles)",
            "showlegend": True, "x": _typed(vertices[:, 0]), "y": _typed(vertices[:, 1]),
            "z": _typed(vertices[:, 2]), "i": _typed(faces[:, 0], "i4"),
            "j": _typed(faces[:, 1], "i4"), "k": _typed(faces[:, 2], "i4"),
            "vertexcolor": placeholder, "hoverinfo": "skip",
            # Soft light: the photos' colours carry the shading already.
            "lighting": {"ambient": 0.8, "diffuse": 0.3, "specular": 0.05},
        })
    clouds = len(kept) + len(meshes)
    if cameras is not None:
        xs: list[float | None] = []
        ys: list[float | None] = []
        zs: list[float | None] = []
        centres, labels = [], []
        for name, corners in zip(cameras.names, np.asarray(cameras.corners, dtype=np.float64)):
            if not np.all(np.isfinite(corners)):
                continue
            c, q = corners[0], corners[1:]
            path = [c, q[0], q[1], c, q[2], q[3], c, q[0], q[3], q[2], q[1]]
            for p in path:
                xs.append(float(p[0]))
                ys.append(float(p[1]))
                zs.append(float(p[2]))
            xs.append(None)
            ys.append(None)
            zs.append(None)
            centres.append(c)
            labels.append(name)
        if centres:
            shown.append(np.array(centres))
            data.append({"type": "scatter3d", "mode": "lines", "name": f"cameras ({len(labels)})",
                         "x": xs, "y": ys, "z": zs, "hoverinfo": "skip",
                         "line": {"color": "#d62728", "width": 3}})
            cen = np.array(centres)
            data.append({"type": "scatter3d", "mode": "markers", "name": "camera names",
                         "x": cen[:, 0].tolist(), "y": cen[:, 1].tolist(),
                         "z": cen[:, 2].tolist(), "text": labels,
                         "marker": {"size": 3, "color": "#d62728"}, "showlegend": False,
                         "hoverinfo": "text"})
    points_shown = [p for p in shown[:clouds] if len(p)]
    lo, hi = dense_box(np.vstack(points_shown) if points_shown else np.zeros((0, 3)))
    if len(shown) > clouds:  # keep the cameras inside the box
        lo, hi = np.minimum(lo, shown[-1].min(axis=0)), np.maximum(hi, shown[-1].max(axis=0))
    pad = 0.05 * (hi - lo) + 1e-9
    lo, hi = lo - pad, hi + pad
    span = hi - lo
    ratio = span / span.max()
    annotations = []
    if cameras is not None and centres:
        # Names as scene annotations (drawn over the points, on a white ground), a few
        # percent of the box apart: neighbouring cameras would print over each other.
        cen = np.array(centres)
        for i in _label_positions(cen, 0.06 * float(np.linalg.norm(span))):
            annotations.append({"x": float(cen[i, 0]), "y": float(cen[i, 1]),
                                "z": float(cen[i, 2]), "text": Path(labels[i]).stem,
                                "showarrow": False, "yshift": 10, "font": {"size": 10},
                                "bgcolor": "rgba(255,255,255,0.75)"})
    axis_titles = ("x (right)", "y (down)", "z (forward)")
    layout = {
        "margin": {"l": 0, "r": 0, "t": 0, "b": 0},
        "legend": {"x": 0.01, "y": 0.99, "bgcolor": "rgba(255,255,255,0.7)"},
        "paper_bgcolor": "#ffffff",
        "uirevision": "keep",
        "scene": {
            "aspectmode": "manual",
            "aspectratio": {"x": float(ratio[0]), "y": float(ratio[1]), "z": float(ratio[2])},
            "camera": {"up": {"x": 0, "y": -1, "z": 0}, "eye": {"x": -0.45, "y": -0.65, "z": -1.2},
                       "center": {"x": 0, "y": 0, "z": 0}},
            "annotations": annotations,
            **{f"{a}axis": {"title": {"text": t}, "range": [float(lo[i]), float(hi[i])],
                            "backgroundcolor": "#f4f4f4", "showbackground": True}
               for i, (a, t) in enumerate(zip("xyz", axis_titles))},
        },
    }
    text = json.dumps({"data": data, "layout": layout}, separators=(",", ":"))
    for placeholder, array in colors.items():
        text = text.replace(f'"{placeholder}"', array)
    return text.replace("</", "<\\/"), notes
