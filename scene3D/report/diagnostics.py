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

__all__ = ["ViewDiagnostics", "view_diagnostics"]


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
    """

    names: tuple[str, ...]
    points_seen: np.ndarray
    rmse_px: np.ndarray
    track_lengths: np.ndarray
    errors_px: np.ndarray
    shared_points: np.ndarray


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
