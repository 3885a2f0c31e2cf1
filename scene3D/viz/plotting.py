"""Figures of a reconstruction or a calibration as matplotlib ``Figure`` objects, for
notebooks and the book's methods. Headless-safe: no pyplot, no windows, no ``plt.show()``.

Each function takes an optional matplotlib ``ax`` (or creates its own figure) and returns
the ``Figure``. The image-like figures (optic flow, epipolar lines, rectified pair,
disparity) are drawn once, by :mod:`scene3D.viz.drawing` with OpenCV at the images' resolution,
and shown here; the command-line tools write those drawings as PNG without matplotlib.
Images are BGR ``uint8`` as cv2 loads them; they are never drawn into.
"""

from __future__ import annotations

import warnings
from collections.abc import Iterator
from contextlib import contextmanager

import numpy as np
from matplotlib.axes import Axes
from matplotlib.figure import Figure

from ..calibration.uncertainty import UncertaintyMap, format_px
from ..geometry.camera import validate_intrinsics
from ..geometry.conventions import FloatArray
from ..geometry.rectification import RectifiedPair
from .drawing import (
    Raster,
    draw_disparity,
    draw_epipolar_lines,
    draw_optic_flow,
    draw_rectified,
    frustum_corners,
    robust_extent,
    subsample_indices,
)


@contextmanager
def quiet_missing_glyphs() -> Iterator[None]:
    """Silence matplotlib's "Glyph ... missing from font(s)" warnings while drawing.

    A view name in a script the font lacks is drawn as boxes, and said twice per character
    on stderr.
    """
    with warnings.catch_warnings():
        warnings.filterwarnings("ignore", message=r"Glyph \d+ .*missing from",
                                category=UserWarning)
        yield


def _axes(ax: Axes | None, ncols: int = 1, figsize: tuple[float, float] = (8, 6),
          projection: str | None = None) -> tuple[Figure, list[Axes]]:
    if ax is not None:
        return ax.figure, [ax]
    fig = Figure(figsize=figsize, layout="constrained")
    axes = [fig.add_subplot(1, ncols, i + 1, projection=projection) for i in range(ncols)]
    return fig, axes


def plot_raster(raster: Raster, ax: Axes | None = None, width_in: float = 10.0) -> Figure:
    """Show a :class:`scene3D.viz.drawing.Raster` (an OpenCV drawing) with its title.

    Parameters
    ----------
    raster : Raster
        A BGR drawing and its title.
    ax : Axes or None, default None
        Axes to draw in; None for a new figure.
    width_in : float, default 10.0
        Width of a new figure (inches).

    Returns
    -------
    Figure
    """
    h, w = raster.image.shape[:2]
    fig, (ax,) = _axes(ax, figsize=(width_in, width_in * h / w + 0.5))
    ax.imshow(raster.image[..., ::-1])
    ax.set_title(raster.title)
    ax.set_axis_off()
    return fig


def plot_optic_flow(
    img1: np.ndarray, pts1: FloatArray, pts2: FloatArray, ax: Axes | None = None
) -> Figure:
    """Arrows from each point of image 1 to its match in image 2, drawn over image 1.

    Parameters
    ----------
    img1 : (H, W, 3) or (H, W) uint8 ndarray
        Image 1, BGR or grey.
    pts1, pts2 : (N, 2) array_like
        Matched pixels in images 1 and 2 (OpenCV convention).
    ax : Axes or None, default None
        Axes to draw in; None for a new figure.

    Returns
    -------
    Figure
    """
    return plot_raster(draw_optic_flow(img1, pts1, pts2), ax)


def plot_epipolar_lines(
    img1: np.ndarray,
    img2: np.ndarray,
    F: FloatArray,
    pts1: FloatArray,
    pts2: FloatArray,
    num_lines: int = 20,
    ax: Axes | None = None,
) -> Figure:
    """Both images with the epipolar lines of a few matches (``x2^T F x1 = 0``).

    Left: image 1 with the lines ``F^T x2`` and the points ``x1``; right: image 2
    with the lines ``F x1`` and the points ``x2``.

    Parameters
    ----------
    img1, img2 : (H, W, 3) or (H, W) uint8 ndarray
        Images 1 and 2, BGR or grey.
    F : (3, 3) array_like
        Fundamental matrix, ``x2^T F x1 = 0``.
    pts1, pts2 : (N, 2) array_like
        Matched pixels in images 1 and 2.
    num_lines : int, default 20
        Number of matches drawn.
    ax : Axes or None, default None
        Axes to draw in; None for a new figure.

    Returns
    -------
    Figure
    """
    return plot_raster(draw_epipolar_lines(img1, img2, F, pts1, pts2, num_lines), ax,
                       width_in=14.0)


def plot_rectified(rectified: RectifiedPair, num_rows: int = 20,
                   ax: Axes | None = None) -> Figure:
    """The rectified images side by side with horizontal guide lines.

    Parameters
    ----------
    rectified : RectifiedPair
        The rectified images.
    num_rows : int, default 20
        Number of guide lines.
    ax : Axes or None, default None
        Axes to draw in; None for a new figure.

    Returns
    -------
    Figure
    """
    return plot_raster(draw_rectified(rectified, num_rows), ax, width_in=14.0)


def _display_axes(points: FloatArray) -> tuple[FloatArray, FloatArray, FloatArray]:
    """Camera-style coordinates to plot axes: x right, z (depth) away, -y up."""
    return points[:, 0], points[:, 2], -points[:, 1]


def _check_cloud(points3d: FloatArray, colors: np.ndarray | None
                 ) -> tuple[FloatArray, np.ndarray | None]:
    """``points3d`` as ``(N, 3) float64`` and ``colors`` as ``(N, 3)`` after checking them."""
    pts = np.asarray(points3d, dtype=np.float64)
    if pts.ndim != 2 or pts.shape[1] != 3:
        hint = (" (a (3, N) array? pass its transpose)"
                if pts.ndim == 2 and pts.shape[0] == 3 else "")
        raise ValueError(f"`points3d` must have shape (N, 3), got {pts.shape}{hint}")
    if colors is None:
        return pts, None
    rgb = np.asarray(colors)
    if rgb.ndim != 2 or rgb.shape[1] != 3:
        raise ValueError(f"`colors` must have shape (N, 3) (RGB, 0-255), got {rgb.shape}")
    if len(rgb) != len(pts):
        raise ValueError(f"`colors` must have one row per point: {len(rgb)} colours for "
                         f"{len(pts)} points")
    return pts, rgb


def plot_point_cloud(
    points3d: FloatArray,
    colors: np.ndarray | None = None,
    ax: Axes | None = None,
    max_points: int = 20000,
) -> Figure:
    """3D scatter of the points, drawn with ``-y`` up and depth ``z`` away.

    The axis limits cover the 2nd to 98th percentile so that a few far points do
    not flatten the view.

    Parameters
    ----------
    points3d : (N, 3) array_like
        Points in one frame, drawn in its axes: the camera-1 frame of a two-view result
        (x right, y down, z forward; in units of the baseline), or the world frame of a
        many-view model.
    colors : (N, 3) uint8, optional
        RGB colour of each point, 0-255 (``TwoViewReconstruction.colors``); None: one
        colour.
    ax : 3D matplotlib Axes, optional
        Drawn into when given, else a new figure.
    max_points : int
        At most this many points are drawn, evenly spaced through the array.

    Raises
    ------
    ValueError
        If ``points3d`` is not ``(N, 3)`` (a ``(3, N)`` array is refused, not drawn as
        three points) or ``colors`` is not ``(N, 3)`` with one row per point.
    """
    points3d, colors = _check_cloud(points3d, colors)
    fig, (ax,) = _axes(ax, figsize=(8, 7), projection="3d")
    idx = subsample_indices(len(points3d), max_points)
    pts = points3d[idx]
    c = None if colors is None else colors[idx] / 255.0
    x, y, z = _display_axes(pts)
    ax.scatter(x, y, z, c=c, s=2, depthshade=False)
    if len(pts):
        lo, hi = robust_extent(np.column_stack([x, y, z]))
        for setter, a, b in zip((ax.set_xlim, ax.set_ylim, ax.set_zlim), lo, hi):
            pad = 0.05 * (b - a) + 1e-9
            setter(a - pad, b + pad)
    ax.set_xlabel("x (right)")
    ax.set_ylabel("z (depth)")
    ax.set_zlabel("-y (up)")
    ax.set_title(f"Point cloud: {len(points3d)} points (unit baseline)")
    return fig


def plot_calibration_coverage(
    image_points: list[FloatArray], image_size: tuple[int, int], counts: np.ndarray,
    ax: Axes | None = None,
) -> Figure:
    """Where the calibration corners fall in the image, over a grid of corner counts.

    Empty cells (especially at the border, where distortion is largest) mean the
    distortion there is extrapolated, not measured.

    Parameters
    ----------
    image_points : list of (N_v, 2) ndarray
        Detected corners of each view (pixels).
    image_size : (int, int)
        ``(width, height)`` in px.
    counts : (rows, cols) int ndarray
        Corners per cell (:func:`scene3D.calibration.solve.corner_coverage`).
    ax : Axes or None, default None
        Axes to draw in; None for a new figure.

    Returns
    -------
    Figure
    """
    fig, (ax,) = _axes(ax, figsize=(8, 6))
    w, h = image_size
    ax.imshow(counts == 0, extent=(0, w, h, 0), cmap="Reds", vmin=0, vmax=2, alpha=0.5)
    for pts in image_points:
        ax.plot(pts[:, 0], pts[:, 1], ".", markersize=2)
    rows, cols = counts.shape
    for x in np.linspace(0, w, cols + 1):
        ax.axvline(x, color="grey", linewidth=0.5)
    for y in np.linspace(0, h, rows + 1):
        ax.axhline(y, color="grey", linewidth=0.5)
    ax.set_xlim(0, w)
    ax.set_ylim(h, 0)
    ax.set_aspect("equal")
    ax.set_title(f"Corner coverage: {len(image_points)} views, "
                 f"{int(np.sum(counts == 0))} of {counts.size} cells empty (red)")
    return fig


def plot_view_errors(
    per_view_errors_px: dict[str, float], rejected_views: dict[str, float] | None = None,
    ax: Axes | None = None,
) -> Figure:
    """Bar chart of the RMS reprojection error of each view (dropped views in red).

    Parameters
    ----------
    per_view_errors_px : dict[str, float]
        RMS reprojection error (px) of each kept view, by name.
    rejected_views : dict[str, float] or None, default None
        Those of the dropped views.
    ax : Axes or None, default None
        Axes to draw in; None for a new figure.

    Returns
    -------
    Figure
    """
    rejected_views = rejected_views or {}
    fig, (ax,) = _axes(ax, figsize=(max(6, 0.4 * (len(per_view_errors_px) + 4)), 4))
    names = list(per_view_errors_px) + list(rejected_views)
    values = list(per_view_errors_px.values()) + list(rejected_views.values())
    colors = ["tab:blue"] * len(per_view_errors_px) + ["tab:red"] * len(rejected_views)
    ax.bar(range(len(names)), values, color=colors)
    ax.set_xticks(range(len(names)), names, rotation=60, ha="right", fontsize=8)
    if per_view_errors_px:
        ax.axhline(float(np.median(list(per_view_errors_px.values()))), color="k",
                   linestyle="--", linewidth=1, label="median")
        ax.legend()
    ax.set_ylabel("RMS reprojection error (px)")
    ax.set_title("Per-view error" + (" (red: dropped as outliers)" if rejected_views else ""))
    return fig


def plot_disparity(disparity: np.ndarray, ax: Axes | None = None) -> Figure:
    """The disparity map (pixels) with a colour bar; invalid pixels (NaN) are white.

    Parameters
    ----------
    disparity : (H, W) ndarray
        Disparity map (px), NaN where invalid.
    ax : Axes or None, default None
        Axes to draw in; None for a new figure.

    Returns
    -------
    Figure
    """
    return plot_raster(draw_disparity(disparity), ax)


def plot_cameras_and_points(
    points3d: FloatArray,
    colors: np.ndarray | None,
    R: FloatArray,
    t: FloatArray,
    K: FloatArray,
    image_size: tuple[int, int],
    ax: Axes | None = None,
    max_points: int = 20000,
) -> Figure:
    """The point cloud with a frustum per camera, in the world frame.

    Frusta are drawn at a depth of 8 % of the extent of the cloud.

    Parameters
    ----------
    points3d : (N, 3) array_like
        Points in the world frame.
    colors : (N, 3) uint8 or None
        RGB colour of each point, 0-255.
    R : (V, 3, 3) array_like
        World-to-camera rotations, ``x_cam = R[v] @ X + t[v]`` for a world point ``X``.
        Views with NaN poses (not registered) are skipped. For a two-view result (world =
        camera-1 frame) pass ``np.stack([np.eye(3), r.R])`` and
        ``np.stack([np.zeros(3), r.t])``.
    t : (V, 3) array_like
        World-to-camera translations (the camera centres are ``-R[v].T @ t[v]``).
    K : (3, 3) array_like
        Intrinsics shared by the views (the frusta's shape).
    image_size : tuple[int, int]
        (width, height) the intrinsics hold for.
    ax, max_points
        As for :func:`plot_point_cloud`.

    Raises
    ------
    ValueError
        If a shape is wrong, ``R`` and ``t`` differ in their number of views, or ``K``
        is not a camera matrix.
    """
    R = np.asarray(R, dtype=np.float64)
    t = np.asarray(t, dtype=np.float64)
    if R.ndim != 3 or R.shape[1:] != (3, 3):
        raise ValueError(f"`R` must have shape (V, 3, 3), got {R.shape}")
    if t.shape != (len(R), 3):
        raise ValueError(f"`t` must have shape (V, 3) with V = {len(R)} like `R`, got {t.shape}")
    K = validate_intrinsics(K)
    if len(image_size) != 2 or min(image_size) <= 0:
        raise ValueError(f"`image_size` must be (width, height), got {image_size!r}")
    fig = plot_point_cloud(points3d, colors, ax=ax, max_points=max_points)
    points3d = np.asarray(points3d, dtype=np.float64)
    ax = fig.axes[0]
    lo, hi = robust_extent(points3d)
    depth = 0.08 * float(np.linalg.norm(hi - lo))
    drawn = 0
    for corners in frustum_corners(R, t, K, image_size, depth):
        if not np.all(np.isfinite(corners)):
            continue
        center, world = corners[0], corners[1:]
        for corner in world:
            ax.plot(*_display_axes(np.array([center, corner])), color="tab:red", linewidth=0.8)
        ax.plot(*_display_axes(np.vstack([world, world[:1]])), color="tab:red", linewidth=0.8)
        drawn += 1
    ax.set_title(f"{len(points3d)} points, {drawn} cameras")
    return fig


def plot_uncertainty_map(umap: UncertaintyMap, ax: Axes | None = None) -> Figure:
    """Heat map of the projection uncertainty (1 sigma, worst direction, pixels) over the
    image, with contours, its median and worst values, and the corners' values.

    Parameters
    ----------
    umap : UncertaintyMap
        The projection uncertainty over the image.
    ax : Axes or None, default None
        Axes to draw in; None for a new figure.

    Returns
    -------
    Figure
    """
    w, h = umap.image_size
    # The image's aspect, with room for the title above and the colour bar beside it.
    fig, (ax,) = _axes(ax, figsize=(9, min(7.2 * h / w, 9.0) + 1.3))
    extent = (-0.5, w - 0.5, h - 0.5, -0.5)
    from matplotlib.colors import LogNorm

    sigma = np.ma.masked_invalid(umap.sigma_px)  # no ray reaches the masked part: blank
    low, high = (float(sigma.min()), float(sigma.max())) if sigma.count() else (1.0, 1.0)
    lo = max(low, 1e-6)
    norm = LogNorm(vmin=lo, vmax=max(high, 1.01 * lo))
    image = ax.imshow(sigma, extent=extent, cmap="magma_r", norm=norm,
                      interpolation="bilinear")
    fig.colorbar(image, ax=ax, label="1 sigma projection error, worst direction (px, log scale)",
                 shrink=0.85)
    levels = [v for v in (0.1, 0.2, 0.5, 1.0, 2.0, 5.0, 10.0, 20.0) if low < v < high]
    if levels:
        contours = ax.contour(umap.xs, umap.ys, sigma, levels=levels, colors="k",
                              linewidths=0.7)
        ax.clabel(contours, fmt="%g px", fontsize=8)
    for value, (x, y, ha, va) in zip(umap.corners_px.values(), (
            (0, 0, "left", "top"), (w - 1, 0, "right", "top"), (w - 1, h - 1, "right", "bottom"),
            (0, h - 1, "left", "bottom"))):
        color = "k" if value <= umap.limit_px else "tab:red"  # NaN (no ray) in red too
        ax.annotate(format_px(value), (x, y), xytext=(6 if ha == "left" else -6,
                                                       -6 if va == "top" else 6),
                    textcoords="offset points", ha=ha, va=va, fontsize=9, color=color,
                    bbox={"boxstyle": "round", "fc": "white", "alpha": 0.8, "lw": 0})
    ax.set_xlim(extent[0], extent[1])
    ax.set_ylim(extent[2], extent[3])
    ax.set_aspect("equal")
    # Short lines: a title wider than the image ran under the colour bar (16:9 photos).
    ax.set_title(f"Projection uncertainty: median {format_px(umap.median_px)},\n"
                 f"worst {format_px(umap.worst_px)}, centre {format_px(umap.centre_px)}"
                 + (f"; no ray reaches {umap.unreachable_share:.1%} (blank)"
                    if umap.unreachable_share else ""))
    return fig
