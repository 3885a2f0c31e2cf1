"""The consistency check: does the model agree with the pairs' own geometry?

Every verified pair carries matches that one essential matrix explains. Once both
views are in a model, the model's cameras imply an essential matrix of their own,
``E = [t_ji]x R_ji`` with ``R_ji = R_j R_i^T`` and ``t_ji = t_j - R_ji t_i``. When the
cameras are right, the pair's matches lie within a pixel or so of its epipolar lines
(median Sampson distance); when a view was registered wrongly (repeated structure
matched to the wrong place) or part of the model folded onto itself (a mirrored
half, a loop closed the wrong way), the pairs that cross the error contradict it by
tens of pixels.

One wrong pair (a false verification between two different windows) does not
condemn a view. A view is suspect when pairs holding most of its verified inliers
contradict the model, or when consistent pairs do not tie it to the rest of the model
(the model holds it only through pairs that contradict it: a fold).
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from ..geometry.conventions import FloatArray, median, skew
from ..geometry.epipolar import essential_distances
from .sfm_model import ModelCheck
from .tracks import connected_components
from .view_data import PairMatches, ViewFeatures

#: A view is suspect when pairs with more than this share of its inliers contradict it.
MAJORITY = 0.5


def pair_distances_px(R_i: FloatArray, t_i: FloatArray, R_j: FloatArray, t_j: FloatArray,
                      pts_i: FloatArray, pts_j: FloatArray, K: FloatArray) -> FloatArray | None:
    """Sampson distances (px) of matches ``(N, 2)`` to the epipolar geometry of two
    world-to-camera poses; None when the centres coincide (no epipolar geometry).

    Parameters
    ----------
    R_i, t_i : (3, 3) and (3,) array_like
        World-to-camera pose of view ``i`` (``x_cam = R_i X + t_i``).
    R_j, t_j : (3, 3) and (3,) array_like
        World-to-camera pose of view ``j``.
    pts_i, pts_j : (N, 2) array_like
        Matched pixels (OpenCV convention) in views ``i`` and ``j``.
    K : (3, 3) array_like
        Intrinsics shared by both views.

    Returns
    -------
    (N,) float64 or None
        Sampson distances in px.
    """
    R_ji = R_j @ R_i.T
    t_ji = t_j - R_ji @ t_i
    scale = np.linalg.norm(t_ji)
    if not np.isfinite(scale) or scale < 1e-12 * max(np.linalg.norm(t_i), np.linalg.norm(t_j),
                                                      1e-300):
        return None
    return essential_distances(skew(t_ji / scale) @ R_ji, pts_i, pts_j, K)


def pair_residual_px(R_i: FloatArray, t_i: FloatArray, R_j: FloatArray, t_j: FloatArray,
                     pts_i: FloatArray, pts_j: FloatArray, K: FloatArray) -> float:
    """Median of :func:`pair_distances_px` (px); NaN when the centres coincide.

    Parameters
    ----------
    R_i, t_i, R_j, t_j, pts_i, pts_j, K
        As in :func:`pair_distances_px`.

    Returns
    -------
    float
        Median Sampson distance in px, or NaN.
    """
    distances = pair_distances_px(R_i, t_i, R_j, t_j, pts_i, pts_j, K)
    return float("nan") if distances is None else median(distances)


def check_model(registered: np.ndarray, R: FloatArray, t: FloatArray,
                pairs: Sequence[PairMatches], features: Sequence[ViewFeatures], K: FloatArray,
                consistency_px: float, reference: int) -> ModelCheck:
    """Check a model's cameras against every verified pair inside it.

    Parameters
    ----------
    registered : (V,) bool
    R, t : (V, 3, 3), (V, 3)
        World-to-camera poses.
    pairs : sequence of PairMatches
    features : sequence of ViewFeatures
    K : (3, 3)
    consistency_px : float
        A pair whose matches lie further than this (median) contradicts the model.
    reference : int
        A view of the model's core (its first view): the component of consistent pairs
        holding most views (ties: the one with ``reference``) is the model's.

    Returns
    -------
    ModelCheck
    """
    inside = [p for p in pairs if registered[p.i] and registered[p.j]]
    residuals = np.array([pair_residual_px(R[p.i], t[p.i], R[p.j], t[p.j],
                                           features[p.i].keypoints[p.idx_i],
                                           features[p.j].keypoints[p.idx_j], K)
                          for p in inside])
    bad = residuals > consistency_px  # NaN (no baseline): no evidence either way
    V = len(registered)
    weight = np.array([p.num_inliers for p in inside], dtype=float)
    ends_i = np.array([p.i for p in inside], dtype=int)
    ends_j = np.array([p.j for p in inside], dtype=int)
    total = np.bincount(ends_i, weight, V) + np.bincount(ends_j, weight, V)
    against = (np.bincount(ends_i[bad], weight[bad], V)
               + np.bincount(ends_j[bad], weight[bad], V))
    suspects = set(np.flatnonzero(registered & (against > MAJORITY * total)).tolist())
    # Components of the consistent pairs: the model's core and what only bad pairs hold.
    label = connected_components(V, ends_i[~bad], ends_j[~bad])
    members = label[registered]
    roots, counts = np.unique(members, return_counts=True)
    best = max(zip(counts, roots == label[reference], roots), key=lambda c: (c[0], c[1]))[2]
    suspects |= set(np.flatnonzero(registered & (label != best)).tolist())
    return ModelCheck(
        pairs_checked=len(inside),
        inconsistent_pairs=tuple((int(i), int(j), float(r)) for i, j, r, b in
                                 zip(ends_i, ends_j, residuals, bad) if b),
        suspect_views=tuple(sorted(int(v) for v in suspects)))
