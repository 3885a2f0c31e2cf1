"""Figures of a reconstruction. Headless-safe: no pyplot, no windows, no ``plt.show()``.

Each function takes an optional matplotlib ``ax`` (or creates its own figure)
and returns the ``Figure``. Images are BGR ``uint8`` as cv2 loads them; they
are never drawn into.
"""

from __future__ import annotations

import numpy as np
from matplotlib.axes import Axes
from matplotlib.figure import Figure

from .epipolar import epipolar_lines
from .geometry import FloatArray, camera_centers
from .rectification import RectifiedPair


def _axes(ax: Axes | None, ncols: int = 1, figsize: tuple[float, float] = (8, 6),
          projection: str | None = None) -> tuple[Figure, list[Axes]]:
    if ax is not None:
        return ax.figure, [ax]
    fig = Figure(figsize=figsize, layout="constrained")
    axes = [fig.add_subplot(1, ncols, i + 1, projection=projection) for i in range(ncols)]
    return fig, axes


def _show_image(ax: Axes, img: np.ndarray, title: str) -> None:
    ax.imshow(img[..., ::-1] if img.ndim == 3 else img, cmap="gray" if img.ndim == 2 else None)
    ax.set_title(title)
    ax.set_axis_off()


def _subsample(n: int, at_most: int, seed: int = 0) -> np.ndarray:
    if n <= at_most:
        return np.arange(n)
    return np.sort(np.random.default_rng(seed).choice(n, at_most, replace=False))


def plot_optic_flow(
    img1: np.ndarray, pts1: FloatArray, pts2: FloatArray, ax: Axes | None = None
) -> Figure:
    """Arrows from each point of image 1 to its match in image 2, drawn over image 1."""
    fig, (ax,) = _axes(ax, figsize=(10, 7))
    grey = img1.mean(axis=2).astype(np.uint8) if img1.ndim == 3 else img1
    _show_image(ax, grey, f"Optic flow: {len(pts1)} tracks (image 1 -> image 2)")
    d = pts2 - pts1
    ax.quiver(pts1[:, 0], pts1[:, 1], d[:, 0], d[:, 1], color="yellow", angles="xy",
              scale_units="xy", scale=1, width=0.0015)
    ax.plot(pts1[:, 0], pts1[:, 1], "r.", markersize=2)
    return fig


def plot_epipolar_lines(
    img1: np.ndarray,
    img2: np.ndarray,
    F: FloatArray,
    pts1: FloatArray,
    pts2: FloatArray,
    num_lines: int = 20,
) -> Figure:
    """Both images with the epipolar lines of a few matches (``x2^T F x1 = 0``).

    Left: image 1 with the lines ``F^T x2`` and the points ``x1``; right: image 2
    with the lines ``F x1`` and the points ``x2``.
    """
    fig, (ax1, ax2) = _axes(None, ncols=2, figsize=(14, 5))
    idx = _subsample(len(pts1), num_lines)
    colors = [tuple(c) for c in np.random.default_rng(1).uniform(0.2, 1.0, (len(idx), 3))]
    for ax, img, pts, lines, title in (
        (ax1, img1, pts1[idx], epipolar_lines(F, pts2[idx], 2), "Image 1"),
        (ax2, img2, pts2[idx], epipolar_lines(F, pts1[idx], 1), "Image 2"),
    ):
        _show_image(ax, img, f"{title}: epipolar lines")
        w = img.shape[1]
        xs = np.array([0.0, w - 1.0])
        for (a, b, c), p, color in zip(lines, pts, colors):
            if abs(b) > 1e-9:
                ax.plot(xs, -(a * xs + c) / b, color=color, linewidth=1)
            ax.plot(p[0], p[1], "o", color=color, markersize=4)
        ax.set_xlim(0, w - 1)
        ax.set_ylim(img.shape[0] - 1, 0)
    return fig


def plot_rectified(rectified: RectifiedPair, num_rows: int = 20) -> Figure:
    """The rectified images side by side with horizontal guide lines."""
    fig, (ax,) = _axes(None, figsize=(14, 5))
    pair = np.hstack([rectified.img1, rectified.img2])
    _show_image(ax, pair, "Rectified images (matches share a row)")
    for y in np.linspace(0, pair.shape[0] - 1, num_rows + 2)[1:-1]:
        ax.axhline(y, color="lime", linewidth=0.6)
    return fig


def _display_axes(points: FloatArray) -> tuple[FloatArray, FloatArray, FloatArray]:
    """Camera-style coordinates to plot axes: x right, z (depth) away, -y up."""
    return points[:, 0], points[:, 2], -points[:, 1]


def plot_point_cloud(
    points3d: FloatArray,
    colors: np.ndarray | None = None,
    ax: Axes | None = None,
    max_points: int = 20000,
) -> Figure:
    """3D scatter of the points (camera-1 frame), drawn with ``-y`` up and depth ``z`` away.

    The axis limits cover the 2nd to 98th percentile so that a few far points do
    not flatten the view.
    """
    fig, (ax,) = _axes(ax, figsize=(8, 7), projection="3d")
    idx = _subsample(len(points3d), max_points)
    pts = points3d[idx]
    c = None if colors is None else colors[idx] / 255.0
    x, y, z = _display_axes(pts)
    ax.scatter(x, y, z, c=c, s=2, depthshade=False)
    if len(pts):
        lo = np.percentile(np.column_stack([x, y, z]), 2, axis=0)
        hi = np.percentile(np.column_stack([x, y, z]), 98, axis=0)
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
    """Bar chart of the RMS reprojection error of each view (dropped views in red)."""
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
    """The disparity map (pixels) with a colour bar; invalid pixels (NaN) are white."""
    fig, (ax,) = _axes(ax, figsize=(9, 6))
    finite = disparity[np.isfinite(disparity)]
    lo, hi = (np.percentile(finite, [1, 99]) if finite.size else (0.0, 1.0))
    image = ax.imshow(disparity, cmap="viridis", vmin=lo, vmax=hi)
    fig.colorbar(image, ax=ax, label="disparity (px)", shrink=0.8)
    ax.set_title(f"Disparity of rectified image 1 ({finite.size / disparity.size:.0%} valid)")
    ax.set_axis_off()
    return fig


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
    """The point cloud with a frustum per camera (world frame, poses ``x_cam = R X + t``).

    Views with NaN poses (not registered) are skipped. Frusta are drawn at a
    depth of 8 % of the extent of the cloud.
    """
    fig = plot_point_cloud(points3d, colors, ax=ax, max_points=max_points)
    ax = fig.axes[0]
    lo, hi = np.percentile(points3d, [2, 98], axis=0) if len(points3d) else (0, 1)
    depth = 0.08 * float(np.linalg.norm(np.asarray(hi) - np.asarray(lo)))
    w, h = image_size
    corners = np.array([[0, 0, 1], [w, 0, 1], [w, h, 1], [0, h, 1]], dtype=float)
    rays = corners @ np.linalg.inv(K).T * depth  # camera frame, at the chosen depth
    drawn = 0
    for R_v, center in zip(R, camera_centers(R, t)):
        if not np.all(np.isfinite(R_v)):
            continue
        world = rays @ R_v + center  # R^T (x - t) for each corner
        for corner in world:
            ax.plot(*_display_axes(np.array([center, corner])), color="tab:red", linewidth=0.8)
        ax.plot(*_display_axes(np.vstack([world, world[:1]])), color="tab:red", linewidth=0.8)
        drawn += 1
    ax.set_title(f"{len(points3d)} points, {drawn} cameras")
    return fig
