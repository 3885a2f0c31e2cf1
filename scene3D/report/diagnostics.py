"""Per-view numbers of a many-view report, read from a model's observations: the points
each view sees, its reprojection error, the track lengths, the reprojection errors and
the points each pair of views shares.

The errors are those of the model as it is, projected with its cameras
(:meth:`scene3D.io.colmap_model.ColmapModel.reprojection_errors_px`); nothing is estimated.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from ..io.colmap_model import ColmapModel

__all__ = ["MAX_GRAPH_VIEWS", "ViewDiagnostics", "grouped_view_graph",
           "verified_inlier_matrix", "view_diagnostics"]

#: Views beyond which the view graph shows groups of consecutive views: a matrix of more
#: rows is too fine to read and grows with the square of the views.
MAX_GRAPH_VIEWS = 100


@dataclass(frozen=True)
class ViewDiagnostics:
    """The per-view table and the histograms of a many-view report.

    ``V`` views in the input order; the histograms are of the first (largest) model.

    Attributes
    ----------
    names : tuple of str
        The views.
    points_seen : (V,) int64
        Observations of each view in the model it is in (0 when in none).
    rmse_px : (V,) float64
        Each view's reprojection error, RMS per coordinate (as the summary's
        ``reprojection_rmse_px``); NaN for a view in no model or without observations.
    track_lengths : (P,) int64
        How many views see each point of the largest model.
    errors_px : (O,) float64
        Distance of each observation of the largest model from its point's projection.
    shared_points : (V, V) int64
        Points of the same model that both views see (the diagonal: ``points_seen``).
    verified_inliers : (V, V) int64 or None
        The inliers of each verified pair (symmetric; 0 for a pair not verified), when the
        reconstruction says which pairs it verified (:func:`verified_inlier_matrix`); None
        for a model read from disk.
    """

    names: tuple[str, ...]
    points_seen: np.ndarray
    rmse_px: np.ndarray
    track_lengths: np.ndarray
    errors_px: np.ndarray
    shared_points: np.ndarray
    verified_inliers: np.ndarray | None = None


def _covisibility(views: np.ndarray, points: np.ndarray, V: int, P: int) -> np.ndarray:
    """``(V, V)`` counts of points seen by both views: a (views x points) incidence matrix
    times its transpose, a block of points at a time (a few MB whatever the size)."""
    out = np.zeros((V, V), dtype=np.float64)
    block = max(1, 2_000_000 // max(V, 1))
    order = np.argsort(points, kind="stable")
    views, points = views[order], points[order]
    starts = np.searchsorted(points, np.arange(0, P + block, block))
    for b, (lo, hi) in enumerate(zip(starts[:-1], starts[1:])):
        if lo == hi:
            continue
        incidence = np.zeros((V, block), dtype=np.float32)
        incidence[views[lo:hi], points[lo:hi] - b * block] = 1.0  # seen twice: once
        out += incidence @ incidence.T
    return np.rint(out).astype(np.int64)


def view_diagnostics(names: Sequence[str], models: Sequence[ColmapModel]) -> ViewDiagnostics:
    """The per-view numbers of ``models`` (the largest first) over the views ``names``.

    Parameters
    ----------
    names : sequence of str
        Every input view, ``V`` of them; a model's image names are found among them (a
        model's image not among them is left out).
    models : sequence of ColmapModel
        The reconstruction's models, the largest first (``MultiViewReconstruction.colmap_model``
        of each, or one model read from disk).

    Returns
    -------
    ViewDiagnostics
    """
    index = {name: v for v, name in enumerate(names)}
    V = len(names)
    seen = np.zeros(V, dtype=np.int64)
    squares = np.zeros(V)
    shared = np.zeros((V, V), dtype=np.int64)
    track_lengths = np.zeros(0, dtype=np.int64)
    errors_px = np.zeros(0)
    for m, model in enumerate(models):
        to_input = np.array([index.get(n, -1) for n in model.names], dtype=np.int64)
        errors = model.reprojection_errors_px() if len(model.obs_view) else np.zeros(0)
        views = to_input[model.obs_view] if len(model.obs_view) else np.zeros(0, np.int64)
        keep = views >= 0
        views, points, errors_kept = views[keep], model.obs_point[keep], errors[keep]
        seen += np.bincount(views, minlength=V)
        squares += np.bincount(views, errors_kept ** 2, minlength=V)
        shared += _covisibility(views, points, V, len(model.points3d))
        if m == 0:
            track_lengths = np.bincount(model.obs_point, minlength=len(model.points3d))
            errors_px = errors
    with np.errstate(invalid="ignore", divide="ignore"):
        # The summary's RMS is over the x and y components: half the squared distance each.
        rmse = np.where(seen > 0, np.sqrt(squares / (2 * np.maximum(seen, 1))), np.nan)
    return ViewDiagnostics(tuple(names), seen, rmse, track_lengths.astype(np.int64),
                           np.asarray(errors_px, dtype=np.float64), shared)


def grouped_view_graph(names: Sequence[str], shared: np.ndarray,
                       max_views: int = MAX_GRAPH_VIEWS) -> tuple[list[str], np.ndarray, int]:
    """The view graph with at most ``max_views`` rows: consecutive views (in the input
    order) grouped, ``group`` at a time, when there are more.

    Parameters
    ----------
    names : sequence of str
        The ``V`` views.
    shared : (V, V) array_like of int
        Points both views see (:attr:`ViewDiagnostics.shared_points`).
    max_views : int, default MAX_GRAPH_VIEWS
        The most rows shown.

    Returns
    -------
    labels : list of str
        A view's name, or ``"FIRST - LAST"`` of a group.
    matrix : (G, G) int64
        The points shared between two groups, summed over their pairs of views; the
        diagonal holds the sharing within a group (the graph does not draw it).
    group : int
        Views per group (1: none grouped; the last group may hold fewer).
    """
    if max_views < 1:
        raise ValueError(f"max_views must be at least 1, got {max_views}")
    shared = np.asarray(shared, dtype=np.int64)
    V = len(names)
    group = max(1, -(-V // max_views))
    if group == 1:
        return list(names), shared.copy(), 1
    starts = np.arange(0, V, group)
    rows = np.add.reduceat(shared, starts, axis=0)
    matrix = np.add.reduceat(rows, starts, axis=1)
    ends = np.minimum(starts + group, V) - 1
    labels = [names[a] if a == e else f"{names[a]} - {names[e]}" for a, e in zip(starts, ends)]
    return labels, matrix, group


def verified_inlier_matrix(edges: Sequence[tuple[int, int, int]], num_views: int) -> np.ndarray:
    """The verified pairs as a symmetric matrix of their inliers.

    Parameters
    ----------
    edges : sequence of (int, int, int)
        ``(a, b, inliers)`` per verified pair
        (:attr:`scene3D.multiview.MultiViewReconstruction.verified_edges`).
    num_views : int
        ``V``.

    Returns
    -------
    (V, V) int64
        ``inliers`` at ``(a, b)`` and ``(b, a)``; 0 elsewhere.
    """
    out = np.zeros((num_views, num_views), dtype=np.int64)
    for a, b, inliers in edges:
        out[a, b] = out[b, a] = inliers
    return out
