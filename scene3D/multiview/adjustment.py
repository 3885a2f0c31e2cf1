"""The bundle adjustments of a growing model (:class:`scene3D.multiview.state.GrowingModel`,
whose base :class:`ModelAdjustment` is): local and global, with the one focal length of
photos without a calibration, its jackknife spread, and the test of a calibration's focal
length.

:class:`ModelAdjustment` holds no state of its own: it works on the attributes
:class:`~scene3D.multiview.state.GrowingModel` sets (keypoint nodes ``xy``, ``node_view``,
``node_point``, ``track_point``, poses ``R``, ``t``, points ``X``, ``K``, ``sigma``,
``registered``, ``reference``, ``focal``, settings ``s`` and the
:class:`~scene3D.engines.timing.StageTimer` ``timer``).
"""

from __future__ import annotations

import dataclasses

import numpy as np

from ..optim.bundle import Observations, bundle_adjust, bundle_adjust_focal
from .focal import longer_side_px
from .points import observation_errors, refine_points
from .settings import refutes_calibration
from .sfm_model import ModelCheck
from .tracks import connected_components

#: Points (at most, about) in the adjustment that tests a calibrated model's focal length.
FOCAL_TEST_POINTS = 1000


class ModelAdjustment:
    """The bundle adjustments of :class:`~scene3D.multiview.state.GrowingModel` (see the
    module docstring)."""

    def remove_observations(self, nodes: np.ndarray) -> None:
        """Drop observations; points left with fewer than two go (their nodes too).

        Parameters
        ----------
        nodes : (M,) int ndarray
            Keypoint nodes whose observations go.
        """
        self.node_point[nodes] = -1
        counts = np.bincount(self.node_point[self.node_point >= 0], minlength=len(self.X))
        thin = counts < 2
        observed = self.node_point >= 0
        self.node_point[observed & thin[np.maximum(self.node_point, 0)]] = -1
        dead = np.flatnonzero(thin)
        self.track_point[np.isin(self.track_point, dead)] = -1

    def fixed_view(self) -> int:
        """The view the adjustments hold fixed: the reference view while it is registered,
        else the first registered view.

        Returns
        -------
        int
        """
        return self.reference if self.registered[self.reference] else int(
            np.flatnonzero(self.registered)[0])

    def adjustment_nodes(self, nodes: np.ndarray) -> np.ndarray:
        """Which of the observations ``nodes`` (every observation of their points) take
        part in bundle adjustment ``(len(nodes),) bool``: those of the points it admits.

        A point that three or more views observe verifies itself (its rays must meet
        in one point); a point of two views does not: a false match that lies along
        the epipolar line, such as the neighbouring window of a repeated facade, fits
        its pair and nothing contradicts it. Where many such matches pass, they bend
        the cameras by more than all the true ones can hold them. So, as GLOMAP
        positions its cameras from tracks of three views or more, a two-view point
        is adjusted only where the multi-view points among ``nodes`` do not hold its
        views: when one of them observes fewer than ``min_multiview_observations``
        of them, or they do not join the two (two parts of the model). The other
        two-view points follow the cameras (:meth:`_adjust`).

        Parameters
        ----------
        nodes : (M,) int ndarray
            Observations (keypoint nodes that have a point).

        Returns
        -------
        (M,) bool ndarray
        """
        point, view = self.node_point[nodes], self.node_view[nodes]
        ids, local, counts = np.unique(point, return_inverse=True, return_counts=True)
        use = counts >= 3
        multi = use[local]
        V = len(self.registered)
        support = np.bincount(view[multi], minlength=V)
        order = np.lexsort((view[multi], local[multi]))
        p_m, v_m = local[multi][order], view[multi][order]
        chain = np.flatnonzero(p_m[1:] == p_m[:-1])  # consecutive views of one point
        label = connected_components(V, v_m[chain], v_m[chain + 1])
        two = counts[local] == 2
        order = np.lexsort((view[two], local[two]))
        p_2, v_2 = local[two][order], view[two][order]
        a, b = v_2[0::2], v_2[1::2]
        weak = support < self.s.min_multiview_observations
        use[p_2[0::2]] = weak[a] | weak[b] | (label[a] != label[b])
        return use[local]

    def _adjust(self, nodes: np.ndarray, fixed: np.ndarray, max_iterations: int,
                tolerance: float, anchors: np.ndarray | None = None,
                refine_focal: bool = False) -> None:
        """Bundle-adjust the points observed at ``nodes`` (all their observations) that
        :meth:`adjustment_nodes` admits and the views observing them but ``fixed``
        (only the observations of free views and of the fixed ``anchors``, when
        given); then the other points follow the cameras (a 3x3 refinement each), and
        observations among ``nodes`` that reproject badly or lie behind a camera are
        dropped. With ``refine_focal`` the one focal length is adjusted too (``self.K``
        changes; :mod:`scene3D.multiview.focal`). Timed as the stage
        ``"bundle_adjustment"``."""
        with self.timer.stage("bundle_adjustment"):
            admitted = self.adjustment_nodes(nodes)
            if anchors is not None:
                taking = np.ones(len(self.registered), dtype=bool)
                taking[fixed] = False
                taking[anchors] = True
                admitted &= taking[self.node_view[nodes]]
            inside = nodes[admitted]
            if anchors is not None:
                inside = self._observed_twice(inside)  # else the point follows
            point_ids, obs = self._adjustment_observations(inside)
            if len(inside):
                if refine_focal and self.focal is not None:
                    fa = bundle_adjust_focal(
                        self.R, self.t, self.X[point_ids], obs, self.K, fixed,
                        self.focal.prior_focal_px, self.focal.prior_sigma_log,
                        max_iterations=max_iterations, tolerance=tolerance,
                        principal_point_shift_px=self.focal.principal_point_sigma
                        * longer_side_px(self.K))
                    R, t, X, self.K, self.focal_adjustment = fa.R, fa.t, fa.points3d, fa.K, fa
                else:
                    R, t, X = bundle_adjust(self.R, self.t, self.X[point_ids], obs, self.K, fixed,
                                            max_iterations=max_iterations, tolerance=tolerance)
                free = np.setdiff1d(np.unique(obs.view), fixed)
                self.R[free], self.t[free] = R[free], t[free]
                self.X[point_ids] = X
            adjusted = np.zeros(len(self.X), dtype=bool)
            adjusted[point_ids] = True
            outside = nodes[~adjusted[self.node_point[nodes]]]
            if len(outside):
                ids, point = np.unique(self.node_point[outside], return_inverse=True)
                views = self.node_view[outside]
                self.X[ids] = refine_points(point, self.xy[outside], self.R[views], self.t[views],
                                            self.K, self.X[ids], sigma=None if self.sigma is None
                                            else self.sigma[outside])
            views, points = self.node_view[nodes], self.node_point[nodes]
            err, depth = observation_errors(self.X[points], self.R[views], self.t[views],
                                            self.xy[nodes], self.K)
            self.remove_observations(nodes[~(err <= self.s.max_reprojection_px) | (depth <= 0)])

    def _observed_twice(self, nodes: np.ndarray) -> np.ndarray:
        """Those of the observations ``nodes`` whose point they observe twice or more: a
        point needs two observations in an adjustment."""
        counts = np.bincount(self.node_point[nodes], minlength=len(self.X))
        return nodes[counts[self.node_point[nodes]] >= 2]

    def _adjustment_observations(self, nodes: np.ndarray) -> tuple[np.ndarray, Observations]:
        """The points ``(P',)`` that ``nodes`` observe, and those observations with the
        points numbered ``0 .. P' - 1`` in that order (and their weights), for an
        adjustment of ``self.X[point_ids]``."""
        point_ids, local = np.unique(self.node_point[nodes], return_inverse=True)
        return point_ids, Observations(self.node_view[nodes], local.ravel(), self.xy[nodes],
                                       None if self.sigma is None else self.sigma[nodes])

    def adjust_local(self, view: int) -> None:
        """The new view and its most co-visible views, with the points they see; of the
        other views that see those points, the most co-visible hold them fixed (as many
        as are free), so that the cost does not grow with the tracks' lengths.

        Parameters
        ----------
        view : int
            The view just registered.
        """
        obs_nodes = np.flatnonzero(self.node_point >= 0)
        obs_view, obs_point = self.node_view[obs_nodes], self.node_point[obs_nodes]
        seen = np.zeros(len(self.X) + 1, dtype=bool)
        seen[obs_point[obs_view == view]] = True
        covisible = np.bincount(obs_view[seen[obs_point]], minlength=len(self.registered))
        covisible[view] = 0
        ranked = np.argsort(-covisible, kind="stable")
        ranked = ranked[covisible[ranked] > 0][:self.s.local_ba_views]
        free = np.r_[view, ranked]
        in_free = np.zeros(len(self.registered), dtype=bool)
        in_free[free] = True
        point_ids = np.unique(obs_point[in_free[obs_view]])
        chosen = np.zeros(len(self.X), dtype=bool)
        chosen[point_ids] = True
        nodes = obs_nodes[chosen[obs_point]]
        shared = np.bincount(self.node_view[nodes], minlength=len(self.registered))
        shared[free] = 0
        fixed = np.flatnonzero(shared)
        anchors = fixed[np.argsort(-shared[fixed], kind="stable")][:len(free)]
        if len(fixed) == 0:
            fixed = anchors = np.array([self.fixed_view()])
        self._adjust(nodes, fixed, max_iterations=8, tolerance=1e-5, anchors=anchors)

    def adjust_global(self, max_iterations: int, tolerance: float = 1e-5) -> None:
        """Bundle-adjust every point and every view but the fixed reference view.

        With a focal length to refine (``focal``) and at least ``focal.min_views`` views,
        the shared focal length is adjusted too (``K`` changes).

        Parameters
        ----------
        max_iterations : int
            Most Levenberg-Marquardt iterations.
        tolerance : float, default 1e-5
            Stop when an iteration gains less than this share of the cost.
        """
        nodes = np.flatnonzero(self.node_point >= 0)
        refine = self.focal is not None and self.registered.sum() >= self.focal.min_views
        if len(nodes):
            self._adjust(nodes, np.array([self.fixed_view()]), max_iterations, tolerance,
                         refine_focal=refine)

    def focal_jackknife_sigma_log(self, groups: int = 4, max_iterations: int = 3) -> float:
        """How far the shared focal length spreads over the views: the grouped jackknife
        standard deviation of ``log f``, from copies of the model adjusted again without
        each of ``groups`` groups of its views (every ``groups``-th registered view; a
        few iterations from the optimum), the model itself unchanged. 0 without a focal
        length to refine, or with fewer than two views a group.

        The adjustment's covariance sees the noise of the observations only; views that
        call for different focal lengths (a principal point or a distortion that the
        model lacks, seen differently from each) show here. A group whose refit fails
        (a singular system) is left out of the spread.

        Parameters
        ----------
        groups : int, default 4
            Number of groups of views.
        max_iterations : int, default 3
            Iterations of each group's refit.

        Returns
        -------
        float
        """
        views = np.flatnonzero(self.registered)
        groups = min(groups, len(views) // 2)
        nodes = np.flatnonzero(self.node_point >= 0)
        if self.focal is None or groups < 2 or not len(nodes):
            return 0.0
        nodes = nodes[self.adjustment_nodes(nodes)]
        logs = []
        for g in range(groups):
            kept = self._observed_twice(nodes[~np.isin(self.node_view[nodes], views[g::groups])])
            point_ids, obs = self._adjustment_observations(kept)
            fixed = self.fixed_view()
            if fixed in views[g::groups]:
                fixed = int(np.setdiff1d(views, views[g::groups])[0])
            try:
                fa = bundle_adjust_focal(self.R, self.t, self.X[point_ids], obs, self.K,
                                         np.array([fixed]), self.focal.prior_focal_px,
                                         self.focal.prior_sigma_log,
                                         max_iterations=max_iterations)
            except (ValueError, np.linalg.LinAlgError):  # as in focal_test: no refit
                continue
            logs.append(np.log(fa.focal_px))
        if len(logs) < 2:
            return 0.0
        spread = np.asarray(logs) - np.mean(logs)
        return float(np.sqrt((len(logs) - 1) / len(logs) * np.sum(spread**2)))

    def focal_test(self, check: ModelCheck) -> ModelCheck:
        """``check`` with the focal length the model's observations call for, for a model
        with a calibration file (:attr:`ModelCheck.focal_scale`): one bundle adjustment
        of copies with the focal length free (a prior of no weight to speak of, 1 in
        log), the model itself unchanged.

        Parameters
        ----------
        check : ModelCheck
            The model's consistency check.

        Returns
        -------
        ModelCheck
        """
        nodes = np.flatnonzero(self.node_point >= 0)
        if self.focal is not None or self.registered.sum() < 3 or not len(nodes):
            return check
        # Every k-th point is plenty for one number to within 15 %: its sigma stays well
        # under a percent, in a fraction of the time of all the points.
        step = max(1, len(self.X) // FOCAL_TEST_POINTS)
        nodes = nodes[self.node_point[nodes] % step == 0]
        point_ids, obs = self._adjustment_observations(nodes)
        try:
            fa = bundle_adjust_focal(self.R, self.t, self.X[point_ids], obs, self.K,
                                     np.array([self.fixed_view()]), float(self.K[0, 0]), 1.0,
                                     max_iterations=20)
        except (ValueError, np.linalg.LinAlgError):
            return check
        scale, sigma_log = float(fa.focal_px / self.K[0, 0]), float(fa.sigma_log)
        return dataclasses.replace(check, focal_scale=scale, focal_scale_sigma_log=sigma_log,
                                   focal_mismatch=refutes_calibration(
                                       scale, sigma_log, int(self.registered.sum()), self.s))
