"""The growing model's state and operations for the incremental mapper
(:mod:`scene3D.multiview.mapper`): tracks, registration, triangulation, the consistency
check; the local and global bundle adjustments are :mod:`scene3D.multiview.adjustment`'s.

State: every keypoint of every view is a node (:mod:`scene3D.multiview.tracks`);
``node_point[n]`` is the point it observes (-1: none), so the observations are
exactly the nodes with a point, and ``track_point[k]`` is the point of track ``k``.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Sequence

import cv2
import numpy as np

from ..engines.timing import StageTimer
from ..geometry.conventions import FloatArray, camera_centers
from ..optim.bundle import Observations, reprojection_residuals
from .adjustment import FOCAL_TEST_POINTS, ModelAdjustment  # noqa: F401 - public here too
from .cameras import pnp_focal_search
from .checks import check_model, pair_distances_px
from .focal import FocalSettings
from .points import max_parallax_deg, observation_errors, triangulate_groups
from .settings import SfMSettings
from .sfm_model import ModelCheck, SfMModel
from .tracks import build_tracks
from .view_data import PairMatches, ViewFeatures
from .weights import keypoint_sigma


class GrowingModel(ModelAdjustment):
    """Mutable state of one growing model (see the module docstring); its bundle
    adjustments are those of :class:`scene3D.multiview.adjustment.ModelAdjustment`."""

    def __init__(self, features: Sequence[ViewFeatures], pairs: list[PairMatches],
                 K: FloatArray, settings: SfMSettings, allowed: np.ndarray,
                 timer: StageTimer, focal: FocalSettings | None = None,
                 view_camera: np.ndarray | None = None,
                 known_cameras: np.ndarray | None = None) -> None:
        self.features, self.K, self.s, self.timer = list(features), K, settings, timer
        # Several cameras (scene3D.multiview.cameras): the camera of each view, which
        # cameras' focal lengths are known (else searched for at their first view),
        # and how each camera's keypoints were rescaled since.
        self.view_camera = view_camera
        if view_camera is not None:
            C = int(view_camera.max()) + 1
            self.camera_known = (np.zeros(C, dtype=bool) if known_cameras is None
                                 else np.array(known_cameras, dtype=bool))
            self.camera_scale = np.ones(C)
        self.focal = focal  # photos without a calibration: global adjustments refine f
        self.focal_adjustment = None  # the last one's scene3D.optim.bundle.FocalAdjustment
        self.allowed = allowed
        self.pairs = [p for p in pairs if allowed[p.i] and allowed[p.j]]
        V = len(features)
        self.xy = np.concatenate([f.keypoints for f in features]).reshape(-1, 2)
        # Relative noise of each keypoint (bundle adjustment's weights), from its size.
        self.sigma = None if not settings.weight_by_size or any(
            f.sizes is None for f in features) else keypoint_sigma(
            np.concatenate([f.sizes for f in features]))
        self.R = np.full((V, 3, 3), np.nan)
        self.t = np.full((V, 3), np.nan)
        self.registered = np.zeros(V, dtype=bool)
        self.blocked = np.zeros(V, dtype=bool)  # taken out by the check: not put back
        self.X = np.zeros((0, 3))
        self.reference = -1
        self._build_tracks()
        self.node_point = np.full(len(self.xy), -1, dtype=int)
        self.track_point = np.full(self.tracks.num_tracks, -1, dtype=int)

    # -- bookkeeping --------------------------------------------------------------------

    def _build_tracks(self) -> None:
        """The tracks of ``self.pairs``, timed as the stage ``"tracks"``."""
        with self.timer.stage("tracks"):
            tracks = build_tracks([len(f.keypoints) for f in self.features], self.pairs)
            self.tracks = tracks
            self.node_view = tracks.node_view
            self.track_nodes, self.track_starts = tracks.members()

    def add_pairs(self, new: list[PairMatches]) -> None:
        """Take further verified pairs: rebuild the tracks, keep every point.

        Parameters
        ----------
        new : list of PairMatches
            Verified pairs; those with a view outside ``allowed`` are ignored.
        """
        self.pairs += [p for p in new if self.allowed[p.i] and self.allowed[p.j]]
        self._build_tracks()
        self._relink_tracks()

    def drop_pairs(self, bad: set[tuple[int, int]]) -> None:
        """Forget pairs that contradict the model (false verifications, e.g. two different
        windows): rebuild the tracks without them and keep, of each point, only the
        observations in the track that holds most of them, so that nothing stays attached
        through a false pair.

        Parameters
        ----------
        bad : set of (int, int)
            The pairs ``(i, j)``, ``i < j``, to forget.
        """
        self.pairs = [p for p in self.pairs if (p.i, p.j) not in bad]
        self._build_tracks()
        obs = np.flatnonzero(self.node_point >= 0)
        point, track = self.node_point[obs], self.tracks.node_track[obs]
        span = self.tracks.num_tracks + 1
        keys, counts = np.unique(point * span + (track + 1), return_counts=True)
        # Per point, the track with most of its observations (ties: the lower track).
        order = np.lexsort((keys, -counts, keys // span))
        first = order[np.r_[True, np.diff(keys[order] // span) != 0]]
        owner = np.full(len(self.X), -2, dtype=int)
        owner[keys[first] // span] = keys[first] % span - 1
        stray = (track < 0) | (track != owner[point])
        self.remove_observations(obs[stray])
        self._relink_tracks()

    def _relink_tracks(self) -> None:
        """``track_point`` from the observations (a track gets the point of its nodes)."""
        self.track_point = np.full(self.tracks.num_tracks, -1, dtype=int)
        obs = np.flatnonzero(self.node_point >= 0)
        tr = self.tracks.node_track[obs]
        has = tr >= 0
        self.track_point[tr[has]] = self.node_point[obs[has]]

    def observations(self) -> tuple[np.ndarray, Observations]:
        nodes = np.flatnonzero(self.node_point >= 0)
        return nodes, Observations(self.node_view[nodes], self.node_point[nodes], self.xy[nodes])

    def centers(self) -> FloatArray:
        return camera_centers(self.R, self.t)

    @property
    def num_points(self) -> int:
        return int(np.count_nonzero(np.bincount(self.node_point[self.node_point >= 0],
                                                minlength=len(self.X)) >= 2))

    def compact(self) -> None:
        """Renumber the points that still have observations."""
        counts = np.bincount(self.node_point[self.node_point >= 0], minlength=len(self.X))
        keep = counts >= 2
        remap = np.full(len(self.X) + 1, -1, dtype=int)
        remap[np.flatnonzero(keep)] = np.arange(int(keep.sum()))
        self.X = self.X[keep]
        self.node_point = remap[self.node_point]
        self.track_point = remap[self.track_point]

    # -- triangulation --------------------------------------------------------------------

    def triangulate(self, tracks: np.ndarray | None = None) -> int:
        """Triangulate tracks without a point that two registered views see
        (``tracks``: only these). Returns the number of new points.

        Parameters
        ----------
        tracks : (T,) int ndarray or None, default None
            Track indices to consider; None for all.

        Returns
        -------
        int
        """
        candidates = np.flatnonzero(self.track_point < 0) if tracks is None else tracks[
            self.track_point[tracks] < 0]
        if len(candidates) == 0:
            return 0
        counts = np.diff(self.track_starts)[candidates]
        group = np.repeat(np.arange(len(candidates)), counts)
        nodes = self.track_nodes[np.repeat(self.track_starts[candidates], counts)
                                 + np.arange(counts.sum()) - np.repeat(np.cumsum(counts) - counts,
                                                                       counts)]
        views = self.node_view[nodes]
        ok = self.registered[views]
        group, nodes, views = group[ok], nodes[ok], views[ok]
        if len(nodes) == 0:
            return 0
        G = len(candidates)
        X = triangulate_groups(group, self.xy[nodes], self.R[views], self.t[views], self.K, G)
        err, depth = observation_errors(X[group], self.R[views], self.t[views], self.xy[nodes],
                                        self.K)
        good = (err <= self.s.max_reprojection_px) & (depth > 0)
        group, nodes, views = group[good], nodes[good], views[good]
        parallax = max_parallax_deg(group, X[group], self.centers()[views], G)
        enough = (np.bincount(group, minlength=G) >= 2) & (parallax >= self.s.min_parallax_deg)
        enough &= np.all(np.isfinite(X), axis=1)
        new = np.flatnonzero(enough)
        ids = np.full(G, -1, dtype=int)
        ids[new] = len(self.X) + np.arange(len(new))
        self.X = np.concatenate([self.X, X[new]])
        take = enough[group]
        self.node_point[nodes[take]] = ids[group[take]]
        self.track_point[candidates[new]] = ids[new]
        return len(new)

    def complete_tracks(self) -> int:
        """Add the registered views of each reconstructed track that see its point within
        the threshold but do not observe it yet. Returns the observations added."""
        tr = self.tracks.node_track
        nodes = np.flatnonzero((tr >= 0) & (self.node_point < 0))
        nodes = nodes[self.registered[self.node_view[nodes]]]
        points = self.track_point[tr[nodes]]
        nodes, points = nodes[points >= 0], points[points >= 0]
        if len(nodes) == 0:
            return 0
        views = self.node_view[nodes]
        err, depth = observation_errors(self.X[points], self.R[views], self.t[views],
                                        self.xy[nodes], self.K)
        good = (err <= self.s.max_reprojection_px) & (depth > 0)
        self.node_point[nodes[good]] = points[good]
        return int(good.sum())

    # -- registration ------------------------------------------------------------------------

    def correspondences(self, view: int) -> tuple[np.ndarray, np.ndarray]:
        """Nodes of ``view`` whose track has a point, and those points.

        Parameters
        ----------
        view : int
            A view index.

        Returns
        -------
        nodes : (M,) int ndarray
            Keypoint nodes of ``view``.
        points : (M,) int ndarray
            Their points (rows of ``X``, world frame).
        """
        nodes = np.arange(self.tracks.offsets[view], self.tracks.offsets[view + 1])
        tr = self.tracks.node_track[nodes]
        nodes, tr = nodes[tr >= 0], tr[tr >= 0]
        points = self.track_point[tr]
        return nodes[points >= 0], points[points >= 0]

    def register(self, view: int) -> bool:
        """Register ``view`` by PnP on its 2D-3D matches. A pose from fewer than
        ``min_registration_inliers`` inliers (but at least
        ``min_confirmed_registration_inliers``) counts only when a verified pair with a
        registered view confirms it (:meth:`pair_confirms`).

        Parameters
        ----------
        view : int
            A view index, not yet registered.

        Returns
        -------
        bool
            True when the view was registered (its world-to-camera pose set).
        """
        nodes, points = self.correspondences(view)
        need = min(self.s.min_registration_inliers, self.s.min_confirmed_registration_inliers)
        if len(nodes) < need:
            return False
        if self.view_camera is not None and not self.camera_known[self.view_camera[view]]:
            # A camera the model has not seen: its focal length is a guess, which the
            # view's 2D-3D matches correct before its pose is found.
            scale, count = pnp_focal_search(self.X[points], self.xy[nodes], self.K,
                                            self.s.pnp_threshold_px)
            if count < need:
                return False
            self.rescale_camera(int(self.view_camera[view]), 1.0 / scale)
        obj, img = self.X[points], self.xy[nodes]
        ok, rvec, tvec, inliers = cv2.solvePnPRansac(
            obj, img, self.K, None, iterationsCount=2000,
            reprojectionError=self.s.pnp_threshold_px, confidence=0.9999,
            flags=cv2.SOLVEPNP_SQPNP)
        if not ok or inliers is None or len(inliers) < need:
            return False
        inl = inliers.ravel()
        rvec, tvec = cv2.solvePnPRefineLM(obj[inl], img[inl], self.K, None, rvec, tvec)
        R, t = cv2.Rodrigues(rvec)[0], tvec.ravel()
        if len(inl) < self.s.min_registration_inliers and not self.pair_confirms(view, R, t):
            return False
        self.R[view], self.t[view] = R, t
        self.registered[view] = True
        self.node_point[nodes[inl]] = points[inl]
        if self.view_camera is not None:
            self.camera_known[self.view_camera[view]] = True
        return True

    def rescale_camera(self, camera: int, factor: float) -> None:
        """Scale the keypoints of ``camera``'s views about the principal point by
        ``factor``: as if its focal length were ``1 / factor`` times the one its keypoints
        were mapped with (:mod:`scene3D.multiview.cameras`).

        Parameters
        ----------
        camera : int
            A camera index (``view_camera``).
        factor : float
            Positive.
        """
        c = self.K[:2, 2]
        for v in np.flatnonzero(self.view_camera == camera):
            rows = slice(self.tracks.offsets[v], self.tracks.offsets[v + 1])
            self.xy[rows] = c + (self.xy[rows] - c) * factor
            f = self.features[v]
            self.features[v] = dataclasses.replace(
                f, keypoints=c + (f.keypoints - c) * factor,
                sizes=None if f.sizes is None else f.sizes * factor)
            if self.sigma is not None:
                self.sigma[rows] *= factor
        self.camera_scale[camera] *= factor

    def pair_confirms(self, view: int, R: FloatArray, t: FloatArray) -> bool:
        """Whether the pose ``(R, t)`` of ``view`` explains a verified pair with a registered
        view: at least ``min_pair_inliers`` of the pair's matches, and
        ``min_confirmed_share`` of them, within ``pnp_threshold_px`` of the epipolar
        geometry the two poses give (Sampson distance). A view whose matches with the
        model's points are few (a corner turned) but whose pair with a registered view is
        strong registers so; a wrong pose from a few 2D-3D matches explains no pair.

        Parameters
        ----------
        view : int
            The view being registered.
        R, t : (3, 3), (3,) ndarray
            Its world-to-camera pose (``x_cam = R X + t``).

        Returns
        -------
        bool
        """
        for p in self.pairs:
            other = p.j if p.i == view else p.i if p.j == view else -1
            if other < 0 or not self.registered[other] or p.num_inliers < self.s.min_pair_inliers:
                continue
            poses = {view: (R, t), other: (self.R[other], self.t[other])}
            distances = pair_distances_px(*poses[p.i], *poses[p.j],
                                          self.features[p.i].keypoints[p.idx_i],
                                          self.features[p.j].keypoints[p.idx_j], self.K)
            if distances is None:
                continue
            explained = int(np.sum(distances <= self.s.pnp_threshold_px))
            if (explained >= self.s.min_pair_inliers
                    and explained >= self.s.min_confirmed_share * p.num_inliers):
                return True
        return False

    def deregister(self, view: int) -> None:
        """Take ``view`` out of the model: its observations go, its pose becomes NaN.

        Parameters
        ----------
        view : int
            A registered view.
        """
        nodes = np.arange(self.tracks.offsets[view], self.tracks.offsets[view + 1])
        self.remove_observations(nodes[self.node_point[nodes] >= 0])
        self.registered[view] = False
        self.R[view], self.t[view] = np.nan, np.nan

    def retriangulate(self) -> None:
        self.complete_tracks()
        self.triangulate()
        self.compact()

    def check(self) -> ModelCheck:
        return check_model(self.registered, self.R, self.t, self.pairs, self.features, self.K,
                           self.s.consistency_px, self.fixed_view())

    def result(self, check: ModelCheck) -> SfMModel:
        """The finished model: ``check`` with :meth:`focal_test`, the points compacted.

        Parameters
        ----------
        check : ModelCheck
            The model's consistency check.

        Returns
        -------
        SfMModel
            World-to-camera poses (``x_cam = R X + t``), points and their colours (of each
            point's first observation), and the reprojection RMSE (px).
        """
        check = self.focal_test(check)
        self.compact()
        nodes, obs = self.observations()
        colors = np.zeros((len(self.X), 3), np.uint8)
        all_colors = np.concatenate([f.colors for f in self.features]).reshape(-1, 3)
        colors[obs.point[::-1]] = all_colors[nodes[::-1]]  # the first observation's colour
        res = reprojection_residuals(self.R, self.t, self.X, obs, self.K)
        rmse = float(np.sqrt(np.mean(res**2))) if len(res) else float("nan")
        return SfMModel(self.registered.copy(), self.R.copy(), self.t.copy(), self.X.copy(),
                        colors, obs, rmse, check, camera_scale=None if self.view_camera is None
                        else self.camera_scale.copy())
