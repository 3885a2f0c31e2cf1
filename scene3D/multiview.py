"""Incremental structure from motion over several views of one calibrated camera.

The book ends with "repeat the procedure for different image pairs" and names
bundle adjustment as the missing step; this module does both, small and readable:

1. features once per image; pairs to match (all pairs for small sets, neighbours
   for ordered sequences);
2. geometric verification of every pair (essential matrix, as in the two-view core);
3. tracks: matches chained across views (union-find), inconsistent ones dropped;
4. initialisation from the pair with the most well-triangulated points;
5. registration of further views by PnP (RANSAC + Levenberg-Marquardt), always
   the view that sees most reconstructed points next;
6. triangulation of new tracks, then bundle adjustment (:mod:`scene3D.bundle`,
   robust loss) after each registration and at the end, with outlier removal.

Frames: world = the camera frame of the first view of the initial pair, poses
world-to-camera ``x_cam = R X + t``. The scale is that of the initial pair
(unit baseline) and is otherwise arbitrary.
"""

from __future__ import annotations

import logging
import os
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from pathlib import Path

import cv2
import numpy as np
from numpy.typing import ArrayLike

from .bundle import Observations, bundle_adjust, reprojection_residuals
from .camera import scale_intrinsics_halved, validate_distortion, validate_intrinsics
from .epipolar import estimate_essential
from .errors import ReconstructionError
from .features import image_features, match_descriptors
from .geometry import FloatArray, camera_centers
from .imageio import BOOK_MAX_WIDTH_PX, ImageSource, image_size, iter_working_images
from .twoview import TwoViewGeometry, TwoViewSettings, reconstruct_from_matches, sample_colors

logger = logging.getLogger(__name__)


@dataclass(frozen=True)
class ViewFeatures:
    """Keypoints of one working image.

    Attributes
    ----------
    keypoints : (N, 2) float64
        Pixels.
    descriptors : (N, D)
    colors : (N, 3) uint8
        RGB at each keypoint.
    norm : int
        The descriptor distance, ``cv2.NORM_L2`` or ``cv2.NORM_HAMMING``.
    """

    keypoints: FloatArray
    descriptors: np.ndarray
    colors: np.ndarray
    norm: int = cv2.NORM_L2


@dataclass(frozen=True)
class SfMSettings:
    """Thresholds of the incremental reconstruction (pixels of the working images).

    Attributes
    ----------
    threshold_px : float
        Essential-matrix inlier threshold for pair verification.
    min_pair_inliers : int
        A pair with fewer verified matches is not used.
    pnp_threshold_px : float
        RANSAC reprojection threshold when registering a view.
    min_registration_inliers : int
        A view needs this many PnP inliers to be registered.
    max_reprojection_px : float
        Observations reprojecting worse are removed (after triangulation and BA).
    min_parallax_deg : float
        New points need at least this triangulation angle.
    neighbours : int
        For ordered sequences: each view is matched with this many following views.
    """

    threshold_px: float = 1.0
    min_pair_inliers: int = 30
    pnp_threshold_px: float = 3.0
    min_registration_inliers: int = 30
    max_reprojection_px: float = 3.0
    min_parallax_deg: float = 1.5
    neighbours: int = 3


@dataclass(frozen=True)
class MultiViewReconstruction:
    """Cameras and points of a multi-view reconstruction.

    Attributes
    ----------
    names : tuple[str, ...]
        One per input view.
    K : (3, 3) float64
        Intrinsics of the working images.
    image_size : tuple[int, int]
        (width, height) of the working images.
    registered : (V,) bool
        Which views have a pose.
    R, t : (V, 3, 3), (V, 3) float64
        World-to-camera poses (NaN for unregistered views).
    points3d : (P, 3) float64
        World points.
    colors : (P, 3) uint8
    observations : Observations
        Every measurement kept, as (view, point, pixel).
    reprojection_rmse_px : float
    pair_selection : str
        How pairs were chosen ("all pairs" or "neighbours (k)").
    verified_pairs : int
    timings_s : dict[str, float]
    """

    names: tuple[str, ...]
    K: FloatArray
    image_size: tuple[int, int]
    registered: np.ndarray
    R: FloatArray
    t: FloatArray
    points3d: FloatArray
    colors: np.ndarray
    observations: Observations
    reprojection_rmse_px: float
    pair_selection: str
    verified_pairs: int
    timings_s: dict[str, float] = field(default_factory=dict)

    @property
    def centers(self) -> FloatArray:
        """Camera centres ``C = -R^T t`` in world coordinates ``(V, 3)``."""
        return camera_centers(self.R, self.t)

    @property
    def mean_track_length(self) -> float:
        return float(len(self.observations.view) / max(len(self.points3d), 1))

    def point_errors_px(self) -> FloatArray:
        """Mean reprojection error of each point over its observations ``(P,)``."""
        err = np.linalg.norm(reprojection_residuals(self.R, self.t, self.points3d,
                                                    self.observations, self.K), axis=1)
        sums = np.bincount(self.observations.point, err, minlength=len(self.points3d))
        counts = np.bincount(self.observations.point, minlength=len(self.points3d))
        return sums / np.maximum(counts, 1)

    @property
    def unregistered(self) -> tuple[str, ...]:
        return tuple(n for n, ok in zip(self.names, self.registered) if not ok)


# -- features and pairs ----------------------------------------------------------------

def extract_features(img: np.ndarray, feature: str = "SIFT",
                     max_features: int = 8000) -> ViewFeatures:
    """Keypoints, descriptors and colours of one BGR image."""
    found = image_features(img, feature, max_features)
    return ViewFeatures(found.pixels, found.descriptors, sample_colors(img, found.pixels),
                        found.norm)


def select_pairs(num_views: int, mode: str = "auto", neighbours: int = 3
                 ) -> tuple[list[tuple[int, int]], str]:
    """Pairs of views to match, and a description of the choice.

    ``"all"``: every pair. ``"sequential"``: each view with its ``neighbours``
    followers (for ordered sequences). ``"auto"``: all pairs up to 20 views,
    neighbours beyond.
    """
    if mode == "auto":
        mode = "all" if num_views <= 20 else "sequential"
    if mode == "all":
        return ([(i, j) for i in range(num_views) for j in range(i + 1, num_views)],
                "all pairs")
    if mode == "sequential":
        return ([(i, j) for i in range(num_views)
                 for j in range(i + 1, min(num_views, i + 1 + neighbours))],
                f"neighbours ({neighbours} following views)")
    raise ValueError(f"`pairs` must be 'auto', 'all' or 'sequential', got {mode!r}")


def verify_pair(f1: ViewFeatures, f2: ViewFeatures, K: FloatArray,
                settings: SfMSettings) -> tuple[np.ndarray, np.ndarray] | None:
    """Indices of matches consistent with one essential matrix, or None."""
    idx1, idx2 = match_descriptors(f1.descriptors, f2.descriptors, f1.norm)
    if len(idx1) < settings.min_pair_inliers:
        return None
    _, inliers = estimate_essential(f1.keypoints[idx1], f2.keypoints[idx2], K,
                                    settings.threshold_px)
    if inliers.sum() < settings.min_pair_inliers:
        return None
    return idx1[inliers], idx2[inliers]


# -- tracks ------------------------------------------------------------------------------

def build_tracks(num_keypoints: Sequence[int],
                 pair_matches: dict[tuple[int, int], tuple[np.ndarray, np.ndarray]]
                 ) -> list[dict[int, int]]:
    """Chain pairwise matches into tracks (union-find over (view, keypoint) nodes).

    Returns one ``{view: keypoint}`` dict per track seen in at least two views;
    tracks that hold two keypoints of one view (inconsistent matches) are dropped.
    """
    offsets = np.concatenate([[0], np.cumsum(num_keypoints)])
    parent = np.arange(offsets[-1])

    def find(a: int) -> int:
        root = a
        while parent[root] != root:
            root = parent[root]
        while parent[a] != root:
            parent[a], a = root, parent[a]
        return root

    for (i, j), (a, b) in pair_matches.items():
        for u, v in zip(offsets[i] + a, offsets[j] + b):
            ru, rv = find(int(u)), find(int(v))
            if ru != rv:
                parent[ru] = rv
    used = np.unique(np.concatenate(
        [np.concatenate([offsets[i] + a, offsets[j] + b]) for (i, j), (a, b)
         in pair_matches.items()])) if pair_matches else np.zeros(0, int)
    groups: dict[int, dict[int, int]] = {}
    bad: set[int] = set()
    view_of = np.searchsorted(offsets, used, side="right") - 1
    for node, view in zip(used, view_of):
        root = find(int(node))
        track = groups.setdefault(root, {})
        if view in track:
            bad.add(root)
        track[int(view)] = int(node - offsets[view])
    return [tr for root, tr in groups.items() if root not in bad and len(tr) >= 2]


# -- triangulation of tracks ---------------------------------------------------------------

def triangulate_track(views: Sequence[int], pixels: FloatArray, R: FloatArray, t: FloatArray,
                      K: FloatArray) -> FloatArray:
    """Linear multi-view triangulation (DLT, H&Z section 12.2) of one track: ``(3,)``."""
    P = K @ np.concatenate([R[list(views)], t[list(views)][:, :, None]], axis=2)  # (n, 3, 4)
    A = np.concatenate([pixels[:, 0:1] * P[:, 2] - P[:, 0], pixels[:, 1:2] * P[:, 2] - P[:, 1]])
    X = np.linalg.svd(A)[2][-1]
    return X[:3] / X[3] if abs(X[3]) > 1e-12 else np.full(3, np.nan)


def _max_parallax_deg(X: FloatArray, centers: FloatArray) -> float:
    rays = X[None, :] - centers
    rays /= np.linalg.norm(rays, axis=1, keepdims=True)
    cos = np.clip(rays @ rays.T, -1.0, 1.0)
    return float(np.degrees(np.arccos(cos.min())))


# -- the incremental reconstruction ----------------------------------------------------------

class _State:
    """Mutable bookkeeping of the incremental reconstruction (private)."""

    def __init__(self, features: list[ViewFeatures], tracks: list[dict[int, int]],
                 K: FloatArray, settings: SfMSettings) -> None:
        self.features, self.tracks, self.K, self.s = features, tracks, K, settings
        n = len(features)
        self.R = np.full((n, 3, 3), np.nan)
        self.t = np.full((n, 3), np.nan)
        self.registered = np.zeros(n, dtype=bool)
        self.track_point = np.full(len(tracks), -1, dtype=int)
        self.points: list[FloatArray] = []
        self.point_obs: list[dict[int, int]] = []  # view -> keypoint, inliers only

    def centers(self) -> FloatArray:
        return camera_centers(self.R, self.t)

    def add_point(self, track_id: int, X: FloatArray, obs: dict[int, int]) -> None:
        self.track_point[track_id] = len(self.points)
        self.points.append(X)
        self.point_obs.append(obs)

    def triangulate_new(self) -> int:
        """Triangulate every track with >= 2 registered views and no point yet."""
        added = 0
        centers = self.centers()
        for tid, track in enumerate(self.tracks):
            if self.track_point[tid] >= 0:
                continue
            views = [v for v in track if self.registered[v]]
            if len(views) < 2:
                continue
            pix = np.array([self.features[v].keypoints[track[v]] for v in views])
            X = triangulate_track(views, pix, self.R, self.t, self.K)
            if not np.all(np.isfinite(X)):
                continue
            cam = np.einsum("vij,j->vi", self.R[views], X) + self.t[views]
            if np.any(cam[:, 2] <= 0):
                continue
            proj = cam @ self.K.T
            err = np.linalg.norm(proj[:, :2] / proj[:, 2:3] - pix, axis=1)
            good = err <= self.s.max_reprojection_px
            if good.sum() < 2:
                continue
            kept = [v for v, g in zip(views, good) if g]
            if _max_parallax_deg(X, centers[kept]) < self.s.min_parallax_deg:
                continue
            self.add_point(tid, X, {v: track[v] for v in kept})
            added += 1
        return added

    def observations(self) -> Observations:
        view, point, xy = [], [], []
        for pid, obs in enumerate(self.point_obs):
            for v, k in obs.items():
                view.append(v)
                point.append(pid)
                xy.append(self.features[v].keypoints[k])
        return Observations(np.array(view, int), np.array(point, int),
                            np.array(xy, np.float64).reshape(-1, 2))

    def adjust(self, fixed_view: int, max_iterations: int = 30) -> None:
        """Bundle adjustment, then removal of bad observations and points."""
        if not self.points:
            return
        obs = self.observations()
        R, t, X = bundle_adjust(self.R, self.t, np.array(self.points), obs, self.K,
                                fixed_view, max_iterations=max_iterations)
        self.R[self.registered], self.t[self.registered] = R[self.registered], t[
            self.registered]
        err = np.linalg.norm(reprojection_residuals(R, t, X, obs, self.K), axis=1)
        cam_z = np.einsum("oij,oj->oi", R[obs.view], X[obs.point])[:, 2] + t[obs.view, 2]
        bad = (err > self.s.max_reprojection_px) | (cam_z <= 0)
        for v, p in zip(obs.view[bad], obs.point[bad]):
            self.point_obs[p].pop(int(v), None)
        self.points = list(X)
        self._drop_thin_points()

    def _drop_thin_points(self) -> None:
        keep = [i for i, o in enumerate(self.point_obs) if len(o) >= 2]
        remap = np.full(len(self.points), -1, dtype=int)
        remap[keep] = np.arange(len(keep))
        self.points = [self.points[i] for i in keep]
        self.point_obs = [self.point_obs[i] for i in keep]
        has = self.track_point >= 0
        self.track_point[has] = remap[self.track_point[has]]

    def correspondences_2d3d(self, view: int) -> tuple[FloatArray, FloatArray, list[int]]:
        obj, img, tids = [], [], []
        for tid, track in enumerate(self.tracks):
            pid = self.track_point[tid]
            if pid >= 0 and view in track:
                obj.append(self.points[pid])
                img.append(self.features[view].keypoints[track[view]])
                tids.append(tid)
        return (np.array(obj, np.float64).reshape(-1, 3), np.array(img, np.float64).reshape(-1, 2),
                tids)

    def register(self, view: int,
                 found: tuple[FloatArray, FloatArray, list[int]] | None = None) -> bool:
        """Register ``view`` by PnP on its 2D-3D matches (``found``: already collected)."""
        obj, img, tids = found if found is not None else self.correspondences_2d3d(view)
        if len(obj) < self.s.min_registration_inliers:
            return False
        ok, rvec, tvec, inliers = cv2.solvePnPRansac(
            obj, img, self.K, None, iterationsCount=2000,
            reprojectionError=self.s.pnp_threshold_px, confidence=0.9999,
            flags=cv2.SOLVEPNP_SQPNP)
        if not ok or inliers is None or len(inliers) < self.s.min_registration_inliers:
            return False
        inl = inliers.ravel()
        rvec, tvec = cv2.solvePnPRefineLM(obj[inl], img[inl], self.K, None, rvec, tvec)
        self.R[view] = cv2.Rodrigues(rvec)[0]
        self.t[view] = tvec.ravel()
        self.registered[view] = True
        for i in inl:  # the view now observes these points
            pid = self.track_point[tids[i]]
            self.point_obs[pid][view] = self.tracks[tids[i]][view]
        return True


def _initial_pair(features: list[ViewFeatures],
                  pair_matches: dict[tuple[int, int], tuple[np.ndarray, np.ndarray]],
                  K: FloatArray, candidates: int = 6
                  ) -> tuple[tuple[int, int], TwoViewGeometry]:
    """The verified pair (among those with most matches) giving most reliable points.

    Raises ``ReconstructionError`` when no candidate is trusted, quoting the doubt
    about the best-scoring one (e.g. a calibration that does not fit).
    """
    ranked = sorted(pair_matches, key=lambda p: len(pair_matches[p][0]), reverse=True)
    best, best_score = None, -1.0
    doubt, doubt_score = "", -1.0
    for i, j in ranked[:candidates]:
        a, b = pair_matches[(i, j)]
        try:
            r = reconstruct_from_matches(features[i].keypoints[a], features[j].keypoints[b], K,
                                         TwoViewSettings())
        except ReconstructionError:
            continue
        # Favour many points seen under a good angle (a wide but well-matched baseline).
        score = r.points3d.shape[0] * min(r.median_parallax_deg, 8.0)
        if r.trusted and score > best_score:
            best, best_score = ((i, j), r), score
        elif not r.trusted and score > doubt_score:
            doubt, doubt_score = f"; the best candidate pair: {r.warnings[0]}", score
    if best is None:
        raise ReconstructionError("no_initial_pair",
                                  "no pair of views gives a trustworthy two-view start" + doubt,
                                  verified_pairs=len(pair_matches))
    return best


def incremental_reconstruction(
    features: list[ViewFeatures],
    pair_matches: dict[tuple[int, int], tuple[np.ndarray, np.ndarray]],
    K: FloatArray,
    settings: SfMSettings | None = None,
    progress: Callable[[str], None] | None = None,
) -> tuple[_State, dict[str, float]]:
    """Run steps 3-6 (tracks to bundle adjustment) on verified matches."""
    s = settings or SfMSettings()
    say = progress or (lambda message: logger.info("%s", message))
    timings: dict[str, float] = {}
    t0 = time.perf_counter()
    tracks = build_tracks([len(f.keypoints) for f in features], pair_matches)
    state = _State(features, tracks, K, s)
    timings["tracks"] = time.perf_counter() - t0

    t0 = time.perf_counter()
    (i, j), r = _initial_pair(features, pair_matches, K)
    state.R[i], state.t[i] = np.eye(3), np.zeros(3)
    state.R[j], state.t[j] = r.R, r.t
    state.registered[[i, j]] = True
    state.triangulate_new()
    state.adjust(fixed_view=i)
    say(f"initialised from views {i} and {j}: {len(state.points)} points")
    timings["initialisation"] = time.perf_counter() - t0

    t_reg, t_ba = 0.0, 0.0
    failed: set[int] = set()
    while True:
        candidates = [v for v in range(len(features)) if not state.registered[v] and
                      v not in failed]
        if not candidates:
            break
        found = {v: state.correspondences_2d3d(v) for v in candidates}
        view = max(found, key=lambda v: len(found[v][0]))
        t1 = time.perf_counter()
        if not state.register(view, found[view]):
            failed.add(view)
            say(f"view {view}: cannot be registered ({len(found[view][0])} 2D-3D matches)")
            continue
        added = state.triangulate_new()
        t2 = time.perf_counter()
        state.adjust(fixed_view=i)
        t3 = time.perf_counter()
        t_reg += t2 - t1
        t_ba += t3 - t2
        say(f"registered view {view} ({state.registered.sum()}/{len(features)}), "
            f"+{added} points, {len(state.points)} in all")
        failed.clear()  # new points may let a failed view register now
    t1 = time.perf_counter()
    state.adjust(fixed_view=i, max_iterations=100)
    state.triangulate_new()
    state.adjust(fixed_view=i, max_iterations=100)
    timings["registration"] = t_reg
    timings["bundle_adjustment"] = t_ba + time.perf_counter() - t1
    return state, timings


def reconstruct_views(
    images: Sequence[ImageSource],
    K: ArrayLike,
    dist: ArrayLike | None = None,
    *,
    max_width: int | None = 2 * BOOK_MAX_WIDTH_PX,
    names: Sequence[str] | None = None,
    feature: str = "SIFT",
    pairs: str = "auto",
    settings: SfMSettings | None = None,
    progress: Callable[[str], None] | None = None,
) -> MultiViewReconstruction:
    """Reconstruct cameras and points from several photos of one calibrated camera.

    Parameters
    ----------
    images : sequence of paths or (H, W[, C]) arrays
        Photos of the same size.
    K : (3, 3) array_like
        Intrinsics of the **native** images.
    dist : array_like, optional
        OpenCV distortion coefficients; the images are undistorted first.
    max_width : int or None
        Halve while wider than this (default 2400: 3072 -> 1536);
        None keeps the native size. The result's ``K`` is for the working size.
    names : sequence of str, optional
        Names for the report (default: file names, or view0, view1, ...).
    pairs : str
        ``"auto"``, ``"all"`` or ``"sequential"`` (see :func:`select_pairs`).
    progress : callable, optional
        Called with one line of text per step (default: logging at INFO).

    Raises
    ------
    ReconstructionError
        Fewer than two views, or no pair gives a trustworthy start.
    FileNotFoundError, ValueError
        Unreadable images or images of different sizes.
    """
    s = settings or SfMSettings()
    say = progress or (lambda message: logger.info("%s", message))
    if names is None:
        names = [Path(src).name if isinstance(src, (str, os.PathLike)) else f"view{i}"
                 for i, src in enumerate(images)]
    names = tuple(names)
    if len(images) < 2:
        raise ReconstructionError("too_few_views", "need at least two images",
                                  views=len(images))
    timings: dict[str, float] = {"features": 0.0}
    t0 = time.perf_counter()
    K = validate_intrinsics(K)
    features: list[ViewFeatures] = []
    # One image after the other (two decoding ahead): each is needed only for its features
    # and their colours, so a long sequence of large photos is never in memory at once.
    loaded = iter_working_images(images, K, validate_distortion(dist), max_width, names)
    for img, _, levels in loaded:
        t1 = time.perf_counter()
        features.append(extract_features(img, feature))
        timings["features"] += time.perf_counter() - t1
        working_size, halvings = image_size(img), levels  # the same for every image
    K = scale_intrinsics_halved(K, halvings)
    timings["load"] = time.perf_counter() - t0 - timings["features"]
    say(f"features: {', '.join(str(len(f.keypoints)) for f in features)} keypoints")

    t0 = time.perf_counter()
    pair_list, selection = select_pairs(len(features), pairs, s.neighbours)
    pair_matches = {}
    for i, j in pair_list:
        verified = verify_pair(features[i], features[j], K, s)
        if verified is not None:
            pair_matches[(i, j)] = verified
    timings["matching"] = time.perf_counter() - t0
    say(f"{len(pair_matches)} of {len(pair_list)} pairs verified ({selection})")

    state, sfm_timings = incremental_reconstruction(features, pair_matches, K, s, say)
    timings.update(sfm_timings)
    obs = state.observations()
    X = np.array(state.points).reshape(-1, 3)
    res = reprojection_residuals(state.R, state.t, X, obs, K)
    colors = np.zeros((len(X), 3), np.uint8)
    for pid, o in enumerate(state.point_obs):
        v, k = next(iter(o.items()))
        colors[pid] = features[v].colors[k]
    timings["total"] = sum(timings.values())
    return MultiViewReconstruction(
        names=names, K=np.asarray(K, np.float64),
        image_size=working_size,
        registered=state.registered.copy(), R=state.R, t=state.t, points3d=X, colors=colors,
        observations=obs, reprojection_rmse_px=float(np.sqrt(np.mean(res**2))),
        pair_selection=selection, verified_pairs=len(pair_matches), timings_s=timings,
    )

