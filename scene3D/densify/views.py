"""Which views a depth map is computed from: neighbours by shared sparse points and
triangulation angle, and each view's depth range from the sparse points it sees.

Both read a sparse model (:class:`scene3D.io.colmap_model.ColmapModel`: world-to-camera
poses ``x_cam = R X + t``, points in the world frame, observations per view).
"""

from __future__ import annotations

import numpy as np

from ..geometry.conventions import FloatArray
from ..io.colmap_model import ColmapModel

#: The triangulation angle a neighbour's shared points are best at, and the spreads of
#: the weight below and above it (deg): MVSNet's view selection (Yao et al., 2018).
ANGLE_PEAK_DEG = 5.0
ANGLE_SPREAD_BELOW_DEG = 1.0
ANGLE_SPREAD_ABOVE_DEG = 10.0


def angle_weight(angle_deg: FloatArray) -> FloatArray:
    """The weight ``(N,)`` of a shared point seen at triangulation angle ``angle_deg``
    ``(N,)``: 1 at :data:`ANGLE_PEAK_DEG`, a Gaussian falling faster below it (little
    parallax, depth poorly fixed) than above (wide baselines still match).

    Parameters
    ----------
    angle_deg : (N,) array_like
        Angles between the two rays (deg).

    Returns
    -------
    (N,) float64 ndarray
    """
    a = np.asarray(angle_deg, np.float64)
    spread = np.where(a <= ANGLE_PEAK_DEG, ANGLE_SPREAD_BELOW_DEG, ANGLE_SPREAD_ABOVE_DEG)
    return np.exp(-((a - ANGLE_PEAK_DEG) ** 2) / (2 * spread ** 2))


def neighbour_scores(model: ColmapModel) -> FloatArray:
    """How well each pair of views suits dense matching ``(V, V)``: the sum over their
    shared sparse points of :func:`angle_weight` of the points' triangulation angles
    (0 on the diagonal and for views that share no point).

    Parameters
    ----------
    model : ColmapModel

    Returns
    -------
    (V, V) float64 ndarray
        Symmetric.
    """
    views = len(model.names)
    centers = model.centers
    scores = np.zeros((views, views))
    seen = [set(model.obs_point[model.obs_view == v].tolist()) for v in range(views)]
    for a in range(views):
        for b in range(a + 1, views):
            shared = np.fromiter(seen[a] & seen[b], dtype=np.int64)
            if shared.size == 0:
                continue
            X = model.points3d[shared]
            ra, rb = X - centers[a], X - centers[b]
            cos = np.sum(ra * rb, axis=1) / (np.linalg.norm(ra, axis=1) *
                                              np.linalg.norm(rb, axis=1))
            angle = np.degrees(np.arccos(np.clip(cos, -1.0, 1.0)))
            scores[a, b] = scores[b, a] = float(angle_weight(angle).sum())
    return scores


def choose_neighbours(scores: FloatArray, count: int, min_share: float = 0.05) -> list[list[int]]:
    """Each view's best ``count`` neighbours by :func:`neighbour_scores`, best first.

    A view scoring less than ``min_share`` of the view's best is left out (a neighbour
    that shares almost nothing only adds noise).

    Parameters
    ----------
    scores : (V, V) array_like
        :func:`neighbour_scores`.
    count : int
        Most neighbours a view.
    min_share : float, default 0.05
        Least score, as a share of the best.

    Returns
    -------
    list of list of int
        For each view, the indices of its neighbours.
    """
    scores = np.asarray(scores, np.float64)
    chosen = []
    for v in range(len(scores)):
        order = [int(u) for u in np.argsort(-scores[v], kind="stable") if u != v]
        top = scores[v, order[0]] if order else 0.0
        chosen.append([u for u in order[:count] if top > 0 and scores[v, u] >= min_share * top])
    return chosen


def depth_range(model: ColmapModel, view: int, margin: float = 0.25) -> tuple[float, float]:
    """The depths ``(near, far)`` to search in ``view``: the 1st to 99th percentile depth
    of the sparse points it sees, widened by ``margin`` of its width in inverse depth on
    each side (where plane sweep spaces its planes), and never behind the camera.

    Parameters
    ----------
    model : ColmapModel
    view : int
        Index into ``model.names``.
    margin : float, default 0.25
        Widening on each side, as a share of the range in inverse depth.

    Returns
    -------
    (float, float)

    Raises
    ------
    ValueError
        The view sees fewer than 10 points in front of it.
    """
    X = model.points3d[model.obs_point[model.obs_view == view]]
    z = (X @ model.R[view].T + model.t[view])[:, 2]
    z = z[z > 0]
    if len(z) < 10:
        raise ValueError(f"view '{model.names[view]}' sees {len(z)} sparse points in front "
                         "of it, too few for a depth range (at least 10)")
    near, far = np.percentile(z, [1, 99])
    inv_near, inv_far = 1 / near, 1 / far
    pad = margin * (inv_near - inv_far)
    inv_far = max(inv_far - pad, 0.5 * inv_far)
    return float(1 / (inv_near + pad)), float(1 / inv_far)
