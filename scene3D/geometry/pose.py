"""Relative pose from an essential matrix: the four decompositions and cheirality.

``E = U diag(1, 1, 0) V^T`` gives ``R = U W V^T`` or ``U W^T V^T`` and
``t = +-u3`` (H&Z section 9.6.2, result 9.19). The right one of the four puts
the triangulated points in front of both cameras (H&Z figure 9.12); we count
over all inliers rather than trusting one point, as the book did.
"""

from __future__ import annotations

import logging
from typing import NamedTuple

import numpy as np
from numpy.typing import ArrayLike

from ..errors import ReconstructionError
from .camera import validate_intrinsics
from .conventions import FloatArray, as_matrix, as_points2d, check_same_length, pose_angle_deg
from .triangulation import in_front_mask, triangulate_points

logger = logging.getLogger(__name__)

_W = np.array([[0.0, -1.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, 1.0]])


def decompose_essential(E: ArrayLike) -> list[tuple[FloatArray, FloatArray]]:
    """The four ``(R, t)`` candidates of an essential matrix.

    Parameters
    ----------
    E : (3, 3) array_like
        Essential matrix, ``E = [t]x R`` with ``x_cam2 = R x_cam1 + t``.


    Returns
    -------
    list of (R, t)
        ``R`` (3, 3) proper rotations (det +1) and ``t`` (3,) unit vectors, in the
        order ``(R1, t), (R1, -t), (R2, t), (R2, -t)``.
    """
    E = as_matrix(E, (3, 3), "E")
    U, _, Vt = np.linalg.svd(E)
    # E is defined up to sign, so flipping U or V keeps it valid and makes R proper.
    if np.linalg.det(U) < 0:
        U = -U
    if np.linalg.det(Vt) < 0:
        Vt = -Vt
    R1 = U @ _W @ Vt
    R2 = U @ _W.T @ Vt
    t = U[:, 2] / np.linalg.norm(U[:, 2])
    return [(R1, t), (R1, -t), (R2, t), (R2, -t)]


def nearest_decomposition(E: ArrayLike, R: ArrayLike, t: ArrayLike
                          ) -> tuple[FloatArray, FloatArray]:
    """The ``(R, t)`` of :func:`decompose_essential` ``(E)`` nearest to the pose ``R`` (3, 3),
    ``t`` (3,) by :func:`scene3D.geometry.pose_angle_deg`. To compare another essential
    matrix's pose with a chosen one without a cheirality test of its own.

    Parameters
    ----------
    E : (3, 3) array_like
        Essential matrix.
    R, t : (3, 3), (3,) array_like
        Reference pose ``x_cam2 = R x_cam1 + t``.

    Returns
    -------
    R : (3, 3) float64 ndarray
    t : (3,) float64 ndarray
        Unit norm.
    """
    return min(decompose_essential(E), key=lambda pose: pose_angle_deg(*pose, R, t))


class PoseChoice(NamedTuple):
    """The decomposition of ``E`` that :func:`choose_pose` picked.

    Attributes
    ----------
    R : (3, 3) float64
        ``R_cam2_from_cam1``, det +1.
    t : (3,) float64
        Unit translation, ``x_cam2 = R x_cam1 + t``; the scale is unknown.
    points3d : (N, 3) float64
        The correspondences triangulated with this pose (camera-1 frame; NaN rows
        at infinity).
    in_front : (N,) bool
        Points in front of both cameras.
    """

    R: FloatArray
    t: FloatArray
    points3d: FloatArray
    in_front: np.ndarray


def choose_pose(
    E: ArrayLike,
    pts1: ArrayLike,
    pts2: ArrayLike,
    K: ArrayLike,
    min_fraction: float = 0.5,
    min_margin: float = 1.5,
) -> PoseChoice:
    """Pick the decomposition of ``E`` that puts most points in front of both cameras.

    Parameters
    ----------
    E : (3, 3) array_like
        Essential matrix, ``x2n^T E x1n = 0``.
    pts1, pts2 : (N, 2) array_like
        Inlier pixels in image 1 and image 2.
    K : (3, 3) array_like
        Intrinsics of both images.
    min_fraction : float
        The winner must put at least this fraction of the points in front.
    min_margin : float
        ... and at least this many times as many as the runner-up.

    Returns
    -------
    PoseChoice
        ``(R, t, points3d, in_front)``.

    Raises
    ------
    ReconstructionError
        ``"no_cheirality_winner"`` when no candidate wins clearly.
    """
    p1 = as_points2d(pts1, "pts1")
    p2 = as_points2d(pts2, "pts2")
    check_same_length(p1, p2)
    K = validate_intrinsics(K)
    candidates = decompose_essential(E)
    scored = []
    for R, t in candidates[::2]:
        # Linear triangulation is odd in t: the points of (R, -t) are those of (R, t), negated.
        points = triangulate_points(p1, p2, K, R, t)
        for sign in (1.0, -1.0):
            mask = in_front_mask(sign * points, R, sign * t)
            scored.append((int(mask.sum()), PoseChoice(R, sign * t, sign * points, mask)))
    scored.sort(key=lambda item: item[0], reverse=True)
    best, runner_up = scored[0][0], scored[1][0]
    logger.debug("cheirality counts: %s", [count for count, _ in scored])
    if best < min_fraction * len(p1) or best < min_margin * runner_up:
        raise ReconstructionError(
            "no_cheirality_winner",
            "no pose puts the points clearly in front of both cameras",
            points=len(p1), best=best, runner_up=runner_up,
        )
    return scored[0][1]
