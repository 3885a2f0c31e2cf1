"""The flow check: a two-view pose against the dense optical flow between the images.

Sparse matches can agree on a wrong pose: on rows of identical windows, a corner matched
to the same corner of the neighbouring window lies a few pixels from its true epipolar
line, and a pose a few degrees off brings dozens of them within the inlier threshold. On
such matches the wrong pose costs less than the true one, so no statistic of the sparse
residuals can tell them apart (docs/benchmarks.md#castle-p19-repeated-windows). Dense
optical flow does not make those mistakes: it is computed coarse to fine with each
pixel's surroundings, so a window is carried along with its wall rather than matched to its twin.

:func:`flow_correspondences` takes the flow between the images (DIS, OpenCV's dense
inverse search) at every textured pixel of a grid whose forward and backward flows
agree; :func:`check_pose_against_flow` refines the pose on them and compares the share
of the flow that lies near the epipolar lines of each. A pose that the sparse matches
got right is already near the flow's optimum (the share gains little); a wrong one gives
way to a pose that explains a tenth of the textured pixels more or beyond
(docs/benchmarks.md#the-dense-flow-check). :func:`check_pose_against_images` does both on
images of at
most :data:`MAX_FLOW_WIDTH_PX`.

Frames as in :mod:`scene3D.geometry`: ``x_cam2 = R x_cam1 + t``, pixels of the working
images.
"""

from __future__ import annotations

from typing import NamedTuple

import cv2
import numpy as np

from ..geometry.camera import scale_intrinsics_halved
from ..geometry.conventions import FloatArray
from ..geometry.epipolar import essential_distances, essential_from_pose
from ..io.images import BOOK_MAX_WIDTH_PX, halve, halving_levels
from ..optim.refinement import refine_relative_pose

#: The flow is taken on images halved while wider than this (the book's rule, 3072 ->
#: 768 px): its gains were measured at 768 px, and at 1536 px it would cost four times as
#: much and resolve errors of half a degree, which the purpose does not ask to flag.
MAX_FLOW_WIDTH_PX = BOOK_MAX_WIDTH_PX
#: The band around the epipolar lines that counts a flow vector as fitting a pose, in
#: pixels: the refinement's loss scale (:func:`scene3D.optim.refinement.refine_relative_pose`).
#: At 1 px a pose a few degrees off still fits nearly all the flow; at 0.25 px the
#: flow's own noise decides.
FLOW_BAND_PX = 0.5
#: Grid of pixels whose flow is taken, in pixels.
GRID_STEP_PX = 2
#: A pixel whose backward flow misses it by more than this is dropped (occlusions, flow
#: failures), in pixels.
MAX_FORWARD_BACKWARD_PX = 1.0
#: Texture: the smaller eigenvalue of the 5x5 structure tensor of the image scaled to
#: 0-1; flat pixels have no flow of their own.
MIN_TEXTURE = 1e-3
#: DIS's variational refinement of each scale's flow (its medium preset: 5). Without it
#: the flows are faster and give the same verdicts (docs/benchmarks.md#the-dense-flow-check).
VARIATIONAL_ITERATIONS = 0
#: Fewer flow correspondences than this give no verdict.
MIN_FLOW_POINTS = 1000
#: The pose is refined on at most this many of them (evenly spread over the list).
MAX_REFINE_POINTS = 6000


def flow_correspondences(gray1: np.ndarray, gray2: np.ndarray, pts1: FloatArray,
                         pts2: FloatArray) -> tuple[FloatArray, FloatArray]:
    """Dense correspondences ``(M, 2), (M, 2)`` from the optical flow of image 1 to image 2.

    ``gray1, gray2`` are the ``uint8`` working images and ``pts1, pts2`` ``(N, 2)`` their
    sparse matches, whose homography (RANSAC, 8 px) warps image 2 onto image 1 before the
    flow, so that the flow only has to find the parallax. The flow (DIS, medium preset
    without its variational refinement) runs both ways; a pixel of the grid is kept where
    it is textured, its flow lands inside image 2 and the backward flow returns within
    :data:`MAX_FORWARD_BACKWARD_PX`. No pose enters: the same correspondences judge any.
    Empty when no homography can be fitted.

    Parameters
    ----------
    gray1, gray2 : (H, W) uint8 ndarray
        Grey working images, one size.
    pts1, pts2 : (N, 2) array_like
        Matched pixels (OpenCV convention) in images 1 and 2.

    Returns
    -------
    q1, q2 : (M, 2) float64 ndarray
        Flow correspondences (pixels).
    """
    h, w = gray1.shape
    H, _ = cv2.findHomography(pts2, pts1, cv2.RANSAC, 8.0)  # image 2 -> image 1
    if H is None or not np.all(np.isfinite(H)) or abs(np.linalg.det(H)) < 1e-12:
        return np.zeros((0, 2)), np.zeros((0, 2))
    warped = cv2.warpPerspective(gray2, H, (w, h))
    covered = cv2.warpPerspective(np.ones_like(gray2), H, (w, h))
    flow = cv2.DISOpticalFlow_create(cv2.DISOPTICAL_FLOW_PRESET_MEDIUM)
    flow.setVariationalRefinementIterations(VARIATIONAL_ITERATIONS)
    forward = flow.calc(gray1, warped, None)
    backward = flow.calc(warped, gray1, None)
    ys, xs = np.mgrid[0:h:GRID_STEP_PX, 0:w:GRID_STEP_PX]
    grid = np.s_[::GRID_STEP_PX, ::GRID_STEP_PX]  # the pixels (ys, xs), by slicing
    step = forward[grid]
    xw, yw = (xs + step[..., 0]).astype(np.float32), (ys + step[..., 1]).astype(np.float32)
    back = cv2.remap(backward, xw, yw, cv2.INTER_LINEAR, borderMode=cv2.BORDER_CONSTANT,
                     borderValue=(1e6, 1e6))
    returned = np.hypot(xw + back[..., 0] - xs, yw + back[..., 1] - ys)
    texture = cv2.cornerMinEigenVal(gray1.astype(np.float32) / 255.0, 5, 3)[grid]
    inside = (xw >= 2) & (xw < w - 2) & (yw >= 2) & (yw < h - 2)
    inside &= covered[np.clip(yw, 0, h - 1).astype(int), np.clip(xw, 0, w - 1).astype(int)] > 0
    keep = inside & (returned < MAX_FORWARD_BACKWARD_PX) & (texture > MIN_TEXTURE)
    q1 = np.column_stack([xs[keep], ys[keep]]).astype(np.float64)
    q2_warped = np.column_stack([xw[keep], yw[keep]]).astype(np.float64)
    q2 = cv2.perspectiveTransform(q2_warped.reshape(-1, 1, 2), np.linalg.inv(H))
    return q1, q2.reshape(-1, 2)


class FlowCheck(NamedTuple):
    """What :func:`check_pose_against_flow` found.

    Attributes
    ----------
    points : int
        Flow correspondences.
    share : float
        Their share within :data:`FLOW_BAND_PX` of the pose's epipolar lines.
    flow_share : float
        The same for the pose refined on the flow.
    R, t : (3, 3), (3,) float64
        The pose refined on the flow, ``x_cam2 = R x_cam1 + t`` (``|t| = 1``).
    """

    points: int
    share: float
    flow_share: float
    R: FloatArray
    t: FloatArray

    @property
    def gain(self) -> float:
        """How much more of the flow the flow's own pose explains (0: the pose is the
        flow's optimum too)."""
        return self.flow_share - self.share


def _share_within_band(R: FloatArray, t: FloatArray, K: FloatArray, q1: FloatArray,
                       q2: FloatArray) -> float:
    distances = essential_distances(essential_from_pose(R, t), q1, q2, K)
    return float(np.mean(distances < FLOW_BAND_PX))


def check_pose_against_flow(R: FloatArray, t: FloatArray, K: FloatArray, q1: FloatArray,
                            q2: FloatArray) -> FlowCheck | None:
    """The pose ``R, t`` against flow correspondences ``q1, q2`` ``(M, 2)``
    (:func:`flow_correspondences`) under the intrinsics ``K`` ``(3, 3)``.

    Refines the pose on at most :data:`MAX_REFINE_POINTS` of them (Cauchy loss of
    scale :data:`FLOW_BAND_PX`, from ``R, t``: the flow's optimum nearest the pose) and
    measures, for both poses, the share of all of them within that band of the
    epipolar lines. None with fewer than :data:`MIN_FLOW_POINTS` correspondences
    (too little texture to judge).

    Parameters
    ----------
    R, t : (3, 3), (3,) array_like
        Relative pose ``x_cam2 = R x_cam1 + t`` (``|t| = 1``: the scale is unknown).
    K : (3, 3) array_like
        Intrinsics shared by both views.
    q1, q2 : (M, 2) array_like
        Flow correspondences (pixels).

    Returns
    -------
    FlowCheck or None
    """
    if len(q1) < MIN_FLOW_POINTS:
        return None
    pick = np.linspace(0, len(q1) - 1, min(len(q1), MAX_REFINE_POINTS)).astype(int)
    R_flow, t_flow = refine_relative_pose(R, t, q1[pick], q2[pick], K, "cauchy", FLOW_BAND_PX)
    return FlowCheck(len(q1), _share_within_band(R, t, K, q1, q2),
                     _share_within_band(R_flow, t_flow, K, q1, q2), R_flow, t_flow)


def check_pose_against_images(R: FloatArray, t: FloatArray, K: FloatArray, gray1: np.ndarray,
                              gray2: np.ndarray, pts1: FloatArray,
                              pts2: FloatArray) -> FlowCheck | None:
    """The pose ``R, t`` against the flow between the ``uint8`` images ``gray1, gray2`` of
    one size, whose intrinsics are ``K`` ``(3, 3)`` and sparse matches ``pts1, pts2``
    ``(N, 2)``: :func:`flow_correspondences` and :func:`check_pose_against_flow`, on the
    images halved while wider than :data:`MAX_FLOW_WIDTH_PX` (the pose does not depend on
    the size).

    Parameters
    ----------
    R, t : (3, 3), (3,) array_like
        Relative pose ``x_cam2 = R x_cam1 + t`` (``|t| = 1``: the scale is unknown).
    K : (3, 3) array_like
        Intrinsics shared by both views.
    gray1, gray2 : (H, W) uint8 ndarray
        Grey working images, one size.
    pts1, pts2 : (N, 2) array_like
        Matched pixels (OpenCV convention) in images 1 and 2.

    Returns
    -------
    FlowCheck or None
    """
    levels = halving_levels(gray1.shape[1], MAX_FLOW_WIDTH_PX)
    scale = 0.5**levels

    def halved(p: FloatArray) -> FloatArray:  # pixel centres, as camera.scale_intrinsics
        return scale * (p + 0.5) - 0.5

    q1, q2 = flow_correspondences(halve(gray1, levels), halve(gray2, levels), halved(pts1),
                                  halved(pts2))
    return check_pose_against_flow(R, t, scale_intrinsics_halved(K, levels), q1, q2)
