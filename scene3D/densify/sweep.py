"""A per-view depth map by plane sweep, coarse to fine, with ZNCC over neighbours.

On the coarsest level of an image pyramid (halved while wider than
``SweepSettings.coarse_width``), every depth hypothesis is a plane ``z = const`` of the
reference camera, the planes spaced evenly in inverse depth; each neighbour image is
warped into the reference view by the plane's homography (Hartley & Zisserman, section
13.1):

    x_j ~ K_j (R_j0 + t_j0 n^T / z) K_0^-1 x_0,   n = (0, 0, 1),

where ``x_j0 = R_j0 x_0 + t_j0`` takes reference-camera coordinates to neighbour ``j``'s.
On each finer level the depth of the level below is refined: a few inverse depths around
it per pixel (half the step of the level below apart), each neighbour sampled where the
pixel's point at that depth projects (``cv2.remap``).

The matching cost of a pixel is ``1 - ZNCC`` over a square window, averaged over the best
``k`` neighbours: a neighbour in which the point falls outside the image drops out, and
one that sees something else there (an occluder) costs more than the others and drops out
of the best ``k``. A depth that only one neighbour supports can be a chance match: the
fusion's consistency check (:mod:`scene3D.densify.fusion`) is what rejects it. The depth
is the hypothesis of lowest cost, refined by a parabola through it and its two neighbours
in inverse depth. Only the running minimum is kept, so memory is a few images, whatever
the number of planes.

Conventions as in :mod:`scene3D.geometry`: pixels in the OpenCV convention, poses
world-to-camera ``x_cam = R X + t``, depth the ``z`` of the camera frame.
"""

from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np

from ..geometry.camera import scale_intrinsics_halved
from ..geometry.conventions import FloatArray
from ..io.images import halve

#: ``1 - ZNCC`` lies in [0, 2]: the cost of a window without texture.
WORST_COST = np.float32(2.0)


@dataclass(frozen=True)
class SweepSettings:
    """How :func:`plane_sweep_depth` matches.

    Attributes
    ----------
    window_px : int
        Side of the ZNCC window (odd), on every level.
    best_k : int
        The cost of a hypothesis is the mean over this many best neighbours.
    min_ncc : float
        Depths whose (averaged) ZNCC is lower are dropped.
    min_texture : float
        Pixels whose window has a grey-level standard deviation lower than this are
        dropped (no texture to match).
    max_planes : int
        Most planes of the coarse sweep.
    plane_step_px : float
        Coarse planes are spaced so that consecutive ones move the image centre by about
        this many pixels in the neighbour where it moves most.
    coarse_width : int
        The sweep runs on the images halved while wider than this; the finer levels
        refine its depths.
    refine_steps : int
        Each finer level tries this many steps either side of the depth from below.
    """

    window_px: int = 7
    best_k: int = 2
    min_ncc: float = 0.6
    min_texture: float = 2.0
    max_planes: int = 192
    plane_step_px: float = 1.0
    coarse_width: int = 400
    refine_steps: int = 2


def plane_homography(K_ref: FloatArray, K_nb: FloatArray, R_nb_from_ref: FloatArray,
                     t_nb_from_ref: FloatArray, depth: float) -> FloatArray:
    """The homography ``(3, 3)`` from reference pixels to neighbour pixels induced by the
    plane ``z = depth`` of the reference camera.

    Parameters
    ----------
    K_ref, K_nb : (3, 3) array_like
        Intrinsics of the reference and the neighbour view.
    R_nb_from_ref, t_nb_from_ref : (3, 3), (3,) array_like
        ``x_nb = R x_ref + t``.
    depth : float
        The plane's depth (> 0).

    Returns
    -------
    (3, 3) float64 ndarray
    """
    n = np.array([0.0, 0.0, 1.0])
    H = K_nb @ (R_nb_from_ref + np.outer(t_nb_from_ref, n) / depth) @ np.linalg.inv(K_ref)
    return H / H[2, 2]


def sweep_depths(K_ref: FloatArray, size: tuple[int, int], neighbours: list[tuple],
                 depth_range: tuple[float, float], settings: SweepSettings) -> FloatArray:
    """The plane depths ``(D,)``, evenly spaced in inverse depth from far to near.

    Their number is what moves the image centre by ``settings.plane_step_px`` between
    consecutive planes in the neighbour where it moves most, between 16 and
    ``settings.max_planes``.

    Parameters
    ----------
    K_ref : (3, 3) array_like
        Reference intrinsics.
    size : (int, int)
        Reference image ``(width, height)``.
    neighbours : list of (K, R, t)
        Each neighbour's intrinsics and pose relative to the reference
        (``x_nb = R x_ref + t``).
    depth_range : (float, float)
        ``(near, far)`` depths, ``0 < near < far``.
    settings : SweepSettings

    Returns
    -------
    (D,) float64 ndarray
    """
    near, far = depth_range
    centre = np.array([(size[0] - 1) / 2, (size[1] - 1) / 2, 1.0])
    ray = np.linalg.inv(K_ref) @ centre
    span = 0.0
    for K, R, t in neighbours:
        ends = [K @ (R @ (ray * z) + t) for z in (near, far)]
        if min(e[2] for e in ends) <= 0:
            span = float(settings.max_planes) * settings.plane_step_px
            break
        a, b = (e[:2] / e[2] for e in ends)
        span = max(span, float(np.linalg.norm(a - b)))
    count = int(np.clip(np.ceil(span / settings.plane_step_px), 16, settings.max_planes))
    return 1.0 / np.linspace(1.0 / far, 1.0 / near, count)


def _box(img: np.ndarray, window: int) -> np.ndarray:
    return cv2.boxFilter(img, cv2.CV_32F, (window, window), borderType=cv2.BORDER_REFLECT)


class _Reference:
    """The reference image of one level with its window statistics."""

    def __init__(self, img: np.ndarray, settings: SweepSettings) -> None:
        self.img = img
        self.window = settings.window_px
        self.mean = _box(img, self.window)
        self.var = np.maximum(_box(img * img, self.window) - self.mean * self.mean, 0.0)
        self.textured = self.var >= settings.min_texture ** 2
        self.min_var = settings.min_texture ** 2

    def cost(self, warped: np.ndarray) -> np.ndarray:
        """``1 - ZNCC`` ``(H, W)`` of a neighbour warped into this view (negative values
        where the neighbour does not see the pixel): inf there, the worst cost where
        the warped window has no texture."""
        outside = warped < 0
        warped[outside] = 0.0
        mean1 = _box(warped, self.window)
        var1 = _box(warped * warped, self.window) - mean1 * mean1
        cov = _box(self.img * warped, self.window) - self.mean * mean1
        cost = 1.0 - cov / np.sqrt(np.maximum(self.var * var1, 1e-6))
        cost[var1 < self.min_var] = WORST_COST
        cost[outside] = np.inf
        return cost


def best_k_cost(costs: np.ndarray, k: int) -> np.ndarray:
    """The mean ``(H, W)`` of the ``k`` lowest finite costs of ``costs`` ``(J, H, W)``
    (fewer where fewer are finite; :data:`WORST_COST` where none is).

    Parameters
    ----------
    costs : (J, H, W) float32 ndarray
        Each neighbour's cost, inf where it does not see the pixel.
    k : int
        How many of the lowest are averaged.

    Returns
    -------
    (H, W) float32 ndarray
    """
    chosen = np.partition(costs, k - 1, axis=0)[:k] if k < len(costs) else costs
    seen = np.isfinite(chosen)
    count = seen.sum(axis=0)
    total = np.where(seen, chosen, 0).sum(axis=0)
    return np.where(count > 0, total / np.maximum(count, 1), WORST_COST).astype(np.float32)


class _RunningBest:
    """The lowest cost over hypotheses 0, 1, 2, ... per pixel, with the costs of the
    hypotheses either side of it (for the parabola)."""

    def __init__(self, shape: tuple[int, int]) -> None:
        self.cost = np.full(shape, np.inf, np.float32)
        self.index = np.full(shape, -1, np.int32)
        self.before = np.full(shape, np.inf, np.float32)
        self.after = np.full(shape, np.inf, np.float32)
        self.previous = np.full(shape, np.inf, np.float32)
        self.count = 0

    def add(self, cost: np.ndarray) -> None:
        i = self.count
        last = self.index == i - 1
        self.after[last] = cost[last]
        better = cost < self.cost
        self.cost[better] = cost[better]
        self.index[better] = i
        self.before[better] = self.previous[better]
        self.after[better] = np.inf
        self.previous = cost
        self.count += 1

    def shift(self) -> np.ndarray:
        """The parabola's offset from the best hypothesis, in hypotheses, in [-0.5, 0.5]."""
        curvature = self.before - 2 * self.cost + self.after
        with np.errstate(invalid="ignore", divide="ignore"):
            shift = np.where(np.isfinite(curvature) & (curvature > 0),
                             0.5 * (self.before - self.after) / curvature, 0.0)
        return np.clip(np.nan_to_num(shift), -0.5, 0.5)


def _sweep(ref: _Reference, K_ref: FloatArray, images: list[np.ndarray], poses: list[tuple],
           inverse: FloatArray, k: int) -> tuple[np.ndarray, _RunningBest]:
    """Inverse depth ``(H, W)`` of the lowest-cost plane of ``inverse`` ``(D,)`` (with
    the parabola's shift) and the running best it came from."""
    h, w = ref.img.shape
    best = _RunningBest((h, w))
    costs = np.empty((len(images), h, w), np.float32)
    for rho in inverse:
        for j, (img, (K, R, t)) in enumerate(zip(images, poses)):
            H = plane_homography(K_ref, K, R, t, 1.0 / rho)
            warped = cv2.warpPerspective(img, H, (w, h), flags=cv2.INTER_LINEAR |
                                         cv2.WARP_INVERSE_MAP, borderMode=cv2.BORDER_CONSTANT,
                                         borderValue=-1.0)
            costs[j] = ref.cost(warped)
        best.add(best_k_cost(costs, k))
    step = inverse[1] - inverse[0]
    chosen = inverse[np.clip(best.index, 0, len(inverse) - 1)] + best.shift() * step
    return chosen.astype(np.float32), best


def _refine(ref: _Reference, K_ref: FloatArray, images: list[np.ndarray], poses: list[tuple],
            start: np.ndarray, step: float, steps: int, k: int
            ) -> tuple[np.ndarray, _RunningBest]:
    """Inverse depth ``(H, W)`` refined around ``start`` ``(H, W)``: ``2 steps + 1``
    hypotheses ``step`` apart per pixel, each neighbour sampled where the pixel's point
    projects."""
    h, w = ref.img.shape
    gx, gy = np.meshgrid(np.arange(w, dtype=np.float64), np.arange(h, dtype=np.float64))
    pix = np.stack([gx, gy, np.ones((h, w))], axis=-1)
    rays = pix @ np.linalg.inv(K_ref).T  # (H, W, 3), z = 1
    projected = []
    for K, R, t in poses:
        a = (rays @ (K @ R).T).astype(np.float32)  # x_nb ~ a + rho b, rho = 1 / z
        projected.append((a, (K @ t).astype(np.float32)))
    best = _RunningBest((h, w))
    costs = np.empty((len(images), h, w), np.float32)
    for offset in range(-steps, steps + 1):
        rho = start + np.float32(offset * step)
        for j, (img, (a, b)) in enumerate(zip(images, projected)):
            zn = a[..., 2] + rho * b[2]
            with np.errstate(divide="ignore", invalid="ignore"):
                mx = (a[..., 0] + rho * b[0]) / zn
                my = (a[..., 1] + rho * b[1]) / zn
            behind = ~(zn > 0) | ~(rho > 0)
            mx[behind] = -1e6
            warped = cv2.remap(img, mx, my, cv2.INTER_LINEAR, borderMode=cv2.BORDER_CONSTANT,
                               borderValue=-1.0)
            costs[j] = ref.cost(warped)
        best.add(best_k_cost(costs, k))
    chosen = start + (best.index - steps + best.shift()).astype(np.float32) * np.float32(step)
    return chosen.astype(np.float32), best


def _upsample(values: np.ndarray, shape: tuple[int, int]) -> np.ndarray:
    """``values`` of a level halved once, repeated onto the pixels of the level above
    (``(H, W)``; the rows and columns halving dropped take their neighbours')."""
    up = np.repeat(np.repeat(values, 2, axis=0), 2, axis=1)
    h, w = shape
    return np.pad(up, ((0, max(h - up.shape[0], 0)), (0, max(w - up.shape[1], 0))),
                  mode="edge")[:h, :w]


def plane_sweep_depth(reference: np.ndarray, K_ref: FloatArray, neighbours: list[tuple],
                      depth_range: tuple[float, float],
                      settings: SweepSettings | None = None) -> tuple[np.ndarray, np.ndarray]:
    """The depth map of ``reference`` from its neighbours (module docstring).

    Parameters
    ----------
    reference : (H, W) uint8 or float32 ndarray
        The reference view, grey, undistorted.
    K_ref : (3, 3) array_like
        Its intrinsics (OpenCV pixels).
    neighbours : list of (image, K, R, t)
        Each neighbour: its grey undistorted image ``(H_j, W_j)``, intrinsics ``(3, 3)``
        and pose relative to the reference, ``x_nb = R x_ref + t``.
    depth_range : (float, float)
        ``(near, far)`` depths searched, ``0 < near < far``.
    settings : SweepSettings or None, default None
        None for the defaults.

    Returns
    -------
    depth : (H, W) float32 ndarray
        Depth (``z`` in the reference camera frame), NaN where no depth passed the
        checks (ZNCC below ``min_ncc``, too little texture, the coarse plane at an end of
        the range, the depth outside it).
    ncc : (H, W) float32 ndarray
        The averaged ZNCC of the chosen depth.

    Raises
    ------
    ValueError
        No neighbour, or a depth range that is not ``0 < near < far``.
    """
    settings = settings or SweepSettings()
    near, far = (float(v) for v in depth_range)
    if not 0 < near < far:
        raise ValueError(f"`depth_range` must be (near, far) with 0 < near < far, got "
                         f"({near:g}, {far:g})")
    if not neighbours:
        raise ValueError("`neighbours` is empty: a depth map needs at least one neighbour")
    K_ref = np.asarray(K_ref, np.float64)
    ref_full = np.asarray(reference, np.float32)
    images_full = [np.asarray(img, np.float32) for img, _, _, _ in neighbours]
    Ks = [np.asarray(K, np.float64) for _, K, _, _ in neighbours]
    Rts = [(np.asarray(R, np.float64), np.asarray(t, np.float64).reshape(3))
           for _, _, R, t in neighbours]
    k = min(settings.best_k, len(neighbours))
    levels = 0
    while (ref_full.shape[1] >> levels) > settings.coarse_width and \
            min(ref_full.shape[:2]) >> (levels + 1) >= 4 * settings.window_px:
        levels += 1

    def level(n: int) -> tuple[_Reference, FloatArray, list[np.ndarray], list[tuple]]:
        return (_Reference(halve(ref_full, n), settings), scale_intrinsics_halved(K_ref, n),
                [halve(img, n) for img in images_full],
                [(scale_intrinsics_halved(K, n), R, t) for K, (R, t) in zip(Ks, Rts)])

    ref, K_level, images, poses = level(levels)
    h, w = ref.img.shape
    planes = 1.0 / sweep_depths(K_level, (w, h), poses, (near, far), settings)
    inverse, best = _sweep(ref, K_level, images, poses, planes, k)
    # The best plane at an end of the range: what lies there may lie beyond it.
    edge = (best.index <= 0) | (best.index >= len(planes) - 1)
    step = float(planes[1] - planes[0])
    for n in range(levels - 1, -1, -1):
        ref, K_level, images, poses = level(n)
        inverse = _upsample(inverse, ref.img.shape)
        edge = _upsample(edge, ref.img.shape)
        step /= 2
        inverse, best = _refine(ref, K_level, images, poses, inverse, step,
                                settings.refine_steps, k)
    ncc = (1.0 - best.cost).astype(np.float32)
    valid = (~edge & (ncc >= settings.min_ncc) & ref.textured
             & (inverse >= 1 / far) & (inverse <= 1 / near))
    with np.errstate(divide="ignore"):
        depth = np.where(valid, 1.0 / inverse, np.nan).astype(np.float32)
    return depth, ncc
