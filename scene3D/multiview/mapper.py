"""Stage 5: the incremental mapper, one model after the other.

1. Initialisation from the verified pair (among those with most matches) giving most
   points under a good triangulation angle (the two-view core, trusted results only).
2. Registration of the view that sees most reconstructed points next (PnP with
   RANSAC, SQPnP, then Levenberg-Marquardt), triangulation of the tracks it opens.
3. A local bundle adjustment after each registration: the new view and its most
   co-visible views are refined with their points, the other views observing those
   points held fixed. Its cost does not grow with the model.
4. A global bundle adjustment whenever the model has grown by a factor
   (``SfMSettings.global_ba_growth``) in views since the last one, then
   re-triangulation (tracks that failed before are tried again with the refined
   cameras, and reconstructed points gain the views that see them within the
   threshold) and the consistency check (:mod:`scene3D.multiview.checks`): a view
   that contradicts its pair geometry is taken out of the model and not put back.
5. When no view can be registered, the views left are matched with further
   candidates (a callback supplied by the pipeline) and tried again; then a final
   global adjustment, re-triangulation and adjustment, and the final check, which is
   recorded in the model.
6. The views left start the next model, until no trusted pair remains among them.

The model's state and its operations are :class:`scene3D.multiview.state.GrowingModel`.
"""

from __future__ import annotations

import dataclasses
import logging
from collections.abc import Callable, Sequence

import numpy as np

from ..engines.timing import StageTimer
from ..errors import ReconstructionError, plural
from ..geometry.conventions import FloatArray, median
from ..twoview import TwoViewGeometry, TwoViewSettings, reconstruct_from_matches
from ..twoview.trust import focal_agreement, focal_mismatch, k_words
from .focal import (
    FocalSettings,
    focal_estimate,
    prior_intrinsics,
    self_calibrated_start,
)
from .settings import SfMSettings
from .sfm_model import FocalEstimate, SfMModel
from .state import GrowingModel
from .view_data import PairMatches, ViewFeatures

logger = logging.getLogger(__name__)

#: Why a view the consistency check took out of a model is in none.
_CONTRADICTED = "its pose contradicted its pair geometry"

#: The start pair's focal length, by its source (:attr:`FocalEstimate.source`), in words.
_START_SOURCE = {"exif": "the EXIF value (the pair could not refine it)",
                 "prior": "the default (the pair could not refine it)",
                 "exif+refined": "the EXIF value refined by the pair",
                 "prior+refined": "self-calibrated by the pair"}

#: ``more_pairs(view, model_views)``: verified pairs of ``view`` with further candidates
#: among ``model_views`` (the pipeline matches them through its engine).
MorePairs = Callable[[int, Sequence[int]], list[PairMatches]]


def _no_pair_left(s: SfMSettings) -> str:
    """Why no model can start when no pair of the views left was verified."""
    return (f"no two views share {s.min_pair_inliers} or more matches that one essential "
            "matrix explains: do the photos overlap, and were they taken from different "
            "places? (a camera turned on one spot, or one photo twice, gives no depth)")


def _first_model_lost(model: SfMModel, start: PairMatches, left_out: dict[int, str],
                      names: Sequence[str], s: SfMSettings, calibrated: bool) -> str:
    """Why the first model, grown from ``start``, cannot be kept: fewer than
    ``s.min_model_views`` views were left in it (the check took the others out)."""
    kept = int(model.registered.sum())
    out = sorted(v for v, why in left_out.items() if why == _CONTRADICTED)
    taken = ""
    if out:
        whose = "its pose" if len(out) == 1 else "their poses"
        taken = (f"; {plural(len(out), 'view')} taken out because {whose} contradicted the pair "
                 f"geometry ({', '.join(names[v] for v in out)})")
    return (f"no model could be kept: the one started from views {names[start.i]} and "
            f"{names[start.j]} ended with {plural(kept, 'view')}, fewer than the "
            f"{s.min_model_views} a model needs{taken}; {_input_hint(calibrated)}")


def _inherited_focal(previous: FocalEstimate, focal_px: float) -> FocalEstimate:
    """Where a further model's focal length starts: the model built before it (photos of
    one camera). Kept as it is, with source ``"inherited"``, when the model has too few
    views to refine it (``FocalSettings.min_views``)."""
    warnings = () if previous.trusted else (
        "it is the focal length of the model built before this one, which is untrusted",)
    return dataclasses.replace(previous, start_focal_px=focal_px, start_pair=None,
                               source="inherited", warnings=warnings)


def _input_hint(calibrated: bool) -> str:
    """What to check in the input when the views give no model."""
    return ("does the calibration fit these photos?" if calibrated else
            "are the photos of one still scene, from one camera at one zoom setting?")


def initial_pair(features: Sequence[ViewFeatures], pairs: Sequence[PairMatches], K: FloatArray,
                 candidates: int = 6, calibrated: bool = False, K_source: str = "calibration"
                 ) -> tuple[PairMatches, TwoViewGeometry] | str:
    """The verified pair (among those with most inliers) giving most reliable points.

    Returns the pair and its two-view geometry, or the reason there is none: first,
    when ``K``'s focal length is known rather than being self-calibrated (``calibrated``:
    a calibration file; or ``K_source="other photos"``: a further model's, from the
    models before it), because the candidates' matches refute it
    (:func:`refuted_focal_length`), trusted candidate or not: a pair whose own focal check
    passed may sit in a wrong pose's valley (docs/benchmarks.md, "The start pairs' focal
    vote, on two CPU levels"); then, when no candidate is trusted, quoting the doubt about the
    best-scoring one. ``K_source`` names where ``K`` came from in the pairs' warnings
    (:data:`scene3D.twoview.trust.K_SOURCES`).

    Parameters
    ----------
    features : sequence of ViewFeatures
        The views' features.
    pairs : sequence of PairMatches
        Verified pairs.
    K : (3, 3) array_like
        Intrinsics shared by the views.
    candidates : int, default 6
        Number of pairs with most inliers that are tried.
    calibrated : bool, default False
        ``K``'s focal length comes from a calibration file.
    K_source : str, default "calibration"
        Where ``K`` came from (:data:`scene3D.twoview.trust.K_SOURCES`).

    Returns
    -------
    (PairMatches, TwoViewGeometry) or str
        The pair and its geometry (``x_cam2 = R x_cam1 + t``, ``|t| = 1``: the scale is
        unknown), or the reason there is none.
    """
    ranked = sorted(pairs, key=lambda p: (-p.num_inliers, p.i, p.j))
    best, best_score = None, -1.0
    doubt, doubt_score = "", -1.0
    settings = TwoViewSettings()
    answered: list[TwoViewGeometry] = []
    for pair in ranked[:candidates]:
        try:
            r = reconstruct_from_matches(features[pair.i].keypoints[pair.idx_i],
                                         features[pair.j].keypoints[pair.idx_j], K, settings,
                                         K_source=K_source)
        except ReconstructionError:
            continue
        answered.append(r)
        # Favour many points seen under a good angle (a wide but well-matched baseline).
        score = r.points3d.shape[0] * min(r.median_parallax_deg, 8.0)
        if r.trusted and score > best_score:
            best, best_score = (pair, r), score
        elif not r.trusted and score > doubt_score:
            doubt, doubt_score = f"; the best candidate pair: {r.warnings[0]}", score
    if calibrated or K_source == "other photos":
        refuted = refuted_focal_length(answered, settings, K_source)
        if refuted:
            return refuted
    if best is None:
        return "no pair of views gives a trustworthy two-view start" + doubt
    return best


def refuted_focal_length(candidates: Sequence[TwoViewGeometry], settings: TwoViewSettings,
                         K_source: str = "calibration") -> str:
    """Why the candidate start pairs refute ``K``'s focal length, or ``""``.

    Each candidate's matches fit a focal length ``focal_scale`` times ``K``'s. Those
    that can tell vote: a pair refutes ``K`` (:func:`scene3D.twoview.trust.focal_mismatch`)
    or confirms it (:func:`scene3D.twoview.trust.focal_agreement`); a pair whose matches
    leave the focal length wide open abstains. ``K`` is refuted when at least two pairs
    refute it and they outnumber those that confirm it. Counting the abstaining pairs
    against the refutation, as a plain majority of the candidates did, left the verdict
    to pairs that say nothing about it, and so to a CPU's floating point (docs/benchmarks.md,
    "The start pairs' focal vote, on two CPU levels").

    Parameters
    ----------
    candidates : sequence of TwoViewGeometry
        The candidates' two-view results under ``K``.
    settings : TwoViewSettings
        The two-view focal check's limits (``max_focal_mismatch``,
        ``focal_mismatch_sigmas``).
    K_source : str
        Where ``K`` came from, a key of :data:`scene3D.twoview.trust.K_SOURCES`: the
        reason names it.

    Returns
    -------
    str
        The reason (the refuting pairs' median factor, how many refute, confirm and
        cannot tell), or ``""`` when ``K`` is not refuted.
    """
    refuting, confirming = [], 0
    for r in candidates:
        sigma_log = r.focal_scale_sigma / r.focal_scale
        if focal_mismatch(r.focal_scale, sigma_log, settings):
            refuting.append(r.focal_scale)
        elif focal_agreement(r.focal_scale, sigma_log, settings):
            confirming += 1
    if len(refuting) < 2 or len(refuting) <= confirming:
        return ""
    whose = k_words(K_source).whose
    others = [f"{confirming} {'fits' if confirming == 1 else 'fit'} {whose}"] * bool(confirming)
    if abstaining := len(candidates) - len(refuting) - confirming:
        others.append(f"{abstaining} cannot tell")
    return (f"the candidate pairs to start from fit a focal length "
            f"{median(np.array(refuting)):.2f} times {whose} (the median of "
            f"{len(refuting)}{''.join('; ' + o for o in others)})")


def grow_model(features: Sequence[ViewFeatures], pairs: list[PairMatches], K: FloatArray,
               settings: SfMSettings, allowed: np.ndarray, start: tuple[PairMatches,
                                                                           TwoViewGeometry],
               more_pairs: MorePairs | None, say: Callable[[str], None],
               timer: StageTimer, names: Sequence[str],
               focal: FocalSettings | None = None, focal_start: FocalEstimate | None = None,
               view_camera: np.ndarray | None = None, known_cameras: np.ndarray | None = None,
               ) -> tuple[SfMModel, dict[int, str]]:
    """Grow one model from its initial pair over the ``allowed`` views (steps 2-5).

    With ``focal`` (photos without a calibration; ``focal_start`` says where ``K``'s
    focal length comes from) the global adjustments refine it
    (:mod:`scene3D.multiview.focal`).

    Returns the model and, for the allowed views left out, why.

    Parameters
    ----------
    features : sequence of ViewFeatures
        The views' features.
    pairs : list of PairMatches
        Verified pairs.
    K : (3, 3) array_like
        Intrinsics shared by the views.
    settings : SfMSettings
        Thresholds of registration, triangulation and checks.
    allowed : (V,) bool ndarray
        Views this model may register.
    start : (PairMatches, TwoViewGeometry)
        The initial pair and its two-view geometry (:func:`initial_pair`); its first view
        becomes the reference ``[I | 0]``.
    more_pairs : MorePairs or None
        Matches more pairs on demand; None to use ``pairs`` only.
    say : callable
        Receives one progress line at a time.
    timer : StageTimer
        Times the stages (``"matching"``, ``"registration"``, ``"checks"``,
        ``"bundle_adjustment"``, ``"tracks"``).
    names : sequence of str
        View names used in progress lines.
    focal : FocalSettings or None, default None
        Refine one focal length (photos without a calibration).
    focal_start : FocalEstimate or None, default None
        Where ``K``'s focal length comes from.
    view_camera : (V,) int ndarray or None, default None
        With several cameras, the camera of each view (its keypoints in the reference
        camera's pixels: :mod:`scene3D.multiview.cameras`).
    known_cameras : (C,) bool ndarray or None, default None
        The cameras whose focal lengths the keypoints carry; the others' are searched for
        at their first registration (None: only the initial pair's cameras are known).

    Returns
    -------
    model : SfMModel
        World-to-camera poses (``x_cam = R X + t``) in the reference view's frame.
    reasons : dict[int, str]
        For each allowed view left out, why.
    """
    s = settings
    model = GrowingModel(features, pairs, K, s, allowed, timer, focal, view_camera,
                         known_cameras)
    pair, r = start
    if view_camera is not None:
        model.camera_known[view_camera[[pair.i, pair.j]]] = True
    model.reference = pair.i
    model.R[pair.i], model.t[pair.i] = np.eye(3), np.zeros(3)
    model.R[pair.j], model.t[pair.j] = r.R, r.t
    model.registered[[pair.i, pair.j]] = True
    model.triangulate()
    model.adjust_global(max_iterations=30)
    say(f"initialised from views {names[pair.i]} and {names[pair.j]}: "
        f"{model.num_points} points")
    last_views = 2
    failed: set[int] = set()
    reasons: dict[int, str] = {}
    rounds = 0
    while True:
        open_views = np.flatnonzero(allowed & ~model.registered & ~model.blocked)
        candidates = [int(v) for v in open_views if v not in failed]
        counts = [len(model.correspondences(v)[0]) for v in candidates]
        if not candidates or max(counts) < min(s.min_registration_inliers,
                                               s.min_confirmed_registration_inliers):
            if len(open_views) and more_pairs is not None and rounds < s.retry_rounds:
                rounds += 1
                with timer.stage("matching"):
                    found = [p for v in open_views for p in more_pairs(int(v), np.flatnonzero(
                        model.registered).tolist())]
                say(f"{plural(len(open_views), 'view')} not registered yet: {len(found)} further "
                    f"pairs verified (round {rounds})")
                if found:
                    model.add_pairs(found)
                    failed.clear()
                    continue
            for v in open_views:
                reasons[int(v)] = (f"too few 2D-3D matches ({len(model.correspondences(v)[0])})"
                                   if v not in failed else "PnP found no consistent pose")
            break
        view = candidates[int(np.argmax(counts))]
        with timer.stage("registration"):
            if not model.register(view):
                failed.add(view)
                say(f"view {names[view]}: cannot be registered ({max(counts)} 2D-3D matches)")
                continue
            nodes = np.arange(model.tracks.offsets[view], model.tracks.offsets[view + 1])
            tr = np.unique(model.tracks.node_track[nodes])
            added = model.triangulate(tr[tr >= 0])
        model.adjust_local(view)
        n_views = int(model.registered.sum())
        if n_views >= s.global_ba_growth * last_views:
            model.adjust_global(max_iterations=10)
            with timer.stage("registration"):
                model.retriangulate()
            with timer.stage("checks"):
                check = model.check()
                model.drop_pairs({(i, j) for i, j, _ in check.inconsistent_pairs
                                  if i not in check.suspect_views and j not in check.suspect_views})
            for v in check.suspect_views:
                model.deregister(v)
                model.blocked[v] = True
                reasons[v] = _CONTRADICTED
                say(f"view {names[v]}: taken out, its pose contradicts its pair geometry")
            last_views = int(model.registered.sum())
            if last_views < 2:  # no pair left, so no point: nothing more can register
                say(f"model given up: the check left {plural(last_views, 'view')} in it")
                for v in np.flatnonzero(allowed & ~model.registered & ~model.blocked):
                    reasons[int(v)] = ("the model it could join was given up: the check "
                                       "took the other views out")
                return model.result(check), reasons
        say(f"registered view {names[view]} ({int(model.registered.sum())}/"
            f"{int(allowed.sum())}), "
            f"+{added} points, {model.num_points} in all")
        failed.clear()  # new points may let a failed view register now
    model.adjust_global(max_iterations=30, tolerance=1e-6)
    with timer.stage("registration"):
        model.retriangulate()
    model.adjust_global(max_iterations=30, tolerance=1e-8)
    with timer.stage("checks"):
        check = model.check()
    false_pairs = {(i, j) for i, j, _ in check.inconsistent_pairs
                   if i not in check.suspect_views and j not in check.suspect_views}
    if false_pairs and check.ok:  # the model stands; its last false pairs go, then again
        model.drop_pairs(false_pairs)
        model.adjust_global(max_iterations=30, tolerance=1e-8)
        model.retriangulate()
        model.adjust_global(max_iterations=30, tolerance=1e-8)
        with timer.stage("checks"):
            check = model.check()
    estimate = focal_start
    if focal is not None and focal_start is not None and model.focal_adjustment is not None:
        with timer.stage("bundle_adjustment"):
            spread = model.focal_jackknife_sigma_log()
        estimate = focal_estimate(model.focal_adjustment, focal, focal_start, spread)
        if not estimate.determined:  # keep the prior's focal length, adjusted under it
            say(estimate.warnings[0])
            model.focal, model.K = None, prior_intrinsics(model.K, focal)
            model.adjust_global(max_iterations=30, tolerance=1e-8)
            model.retriangulate()
            check = model.check()
    result = model.result(check)
    if estimate is not None:
        result = dataclasses.replace(result, K=model.K.copy(), focal=estimate)
    return result, reasons


def reconstruct_models(features: Sequence[ViewFeatures], pairs: list[PairMatches],
                       K: FloatArray, settings: SfMSettings | None = None,
                       more_pairs: MorePairs | None = None,
                       progress: Callable[[str], None] | None = None,
                       names: Sequence[str] | None = None,
                       focal: FocalSettings | None = None,
                       start_from: FocalEstimate | None = None,
                       view_camera: np.ndarray | None = None,
                       known_cameras: np.ndarray | None = None,
                       timer: StageTimer | None = None,
                       ) -> tuple[list[SfMModel], dict[int, str], dict[str, float]]:
    """Steps 1-6 on verified pairs: every model the views allow, largest first.

    ``K`` is the calibration's; with ``focal`` (photos without a calibration) it is the
    prior's, the first model's start pair is self-calibrated and every model refines one
    focal length in its global adjustments; a further model starts from the previous
    one's (:mod:`scene3D.multiview.focal`). Each model's ``K`` and ``focal`` say what it
    ended with. With ``focal`` and ``start_from`` (a model of the same views made before,
    whose focal length ``K`` carries: :mod:`scene3D.multiview.lens`), the first model
    starts as a further one does, without self-calibrating a pair again.

    Parameters
    ----------
    features : sequence of ViewFeatures
        The views' features.
    pairs : list of PairMatches
        Verified pairs.
    K : (3, 3) array_like
        Intrinsics: the calibration's, or the prior's with ``focal``.
    settings : SfMSettings or None, default None
        None for the defaults.
    more_pairs : MorePairs or None, default None
        Matches more pairs on demand.
    progress : callable or None, default None
        Receives progress lines; None logs them at INFO.
    names : sequence of str or None, default None
        View names for progress lines; None for the indices.
    focal : FocalSettings or None, default None
        Refine one focal length per model (photos without a calibration).
    start_from : FocalEstimate or None, default None
        A previous model's focal estimate the first model starts from.
    view_camera, known_cameras : ndarray or None, default None
        Several cameras: as in :func:`grow_model`. A model then starts from a pair of
        one camera when one of them gives a start, since a pair's self-calibration finds
        one focal length; else from any pair.
    timer : StageTimer or None, default None
        Times the stages (``"tracks"``, ``"initialisation"``, ``"registration"``,
        ``"bundle_adjustment"``, ``"checks"``, ``"matching"``; listed in this order after
        the stages it has seen); None for a new one.


    Returns
    -------
    models : list of SfMModel
    reasons : dict[int, str]
        For each view in no model, why.
    timings : dict[str, float]
        Seconds per stage: ``timer.seconds`` after the call.

    Raises
    ------
    ReconstructionError
        When not even the first model can start (no trusted pair: reason
        ``"no_initial_pair"``), or the consistency check leaves it fewer than
        ``min_model_views`` views (``"no_model"``: usually a calibration that does not fit).
    """
    s = settings or SfMSettings()
    say = progress or (lambda message: logger.info("%s", message))
    timer = StageTimer() if timer is None else timer
    timer.declare("tracks", "initialisation", "registration", "bundle_adjustment", "checks",
                  "matching")
    V = len(features)
    names = [str(v) for v in range(V)] if names is None else list(names)
    remaining = np.ones(V, dtype=bool)
    models: list[SfMModel] = []
    reasons: dict[int, str] = {}
    while remaining.sum() >= 2:
        with timer.stage("initialisation"):
            inside = [p for p in pairs if remaining[p.i] and remaining[p.j]]
            attempts = [inside]
            if view_camera is not None:  # a start from a pair of one camera first, where one is
                one = [p for p in inside if view_camera[p.i] == view_camera[p.j]]
                attempts = [one, inside] if 0 < len(one) < len(inside) else [inside]
            K_given = K
            for inside in attempts:
                K, focal_start = K_given, None
                if focal is not None and not models and inside and start_from is not None:
                    focal_start = start_from
                    start = initial_pair(features, inside, K, K_source="other photos")
                elif focal is not None and not models and inside:
                    start, K, focal_start = self_calibrated_start(features, inside, K, focal,
                                                                  initial_pair)
                    if not isinstance(start, str):
                        say(f"focal length {K[0, 0]:.1f} px to start with: "
                            f"{_START_SOURCE.get(focal_start.source, focal_start.source)}, "
                            f"views {names[start[0].i]} and {names[start[0].j]}")
                elif focal is not None and inside:
                    K = models[-1].K if models[-1].K is not None else K
                    focal_start = _inherited_focal(models[-1].focal, float(K[0, 0]))
                    start = initial_pair(features, inside, K, K_source="other photos")
                else:
                    start = (initial_pair(features, inside, K, calibrated=focal is None) if inside
                             else _no_pair_left(s))
                if not isinstance(start, str):
                    break
        if isinstance(start, str):
            why = f"{start}; {_input_hint(focal is None)}" if inside else start
            if not models:
                raise ReconstructionError("no_initial_pair", why, verified_pairs=len(pairs))
            no_start = (f"not in a model, and no further one could start from the "
                        f"{plural(int(remaining.sum()), 'view')} left: {why}")
            reasons = {int(v): reasons[v] if reasons.get(v) == _CONTRADICTED else no_start
                       for v in np.flatnonzero(remaining)}
            break
        model, left_out = grow_model(features, pairs, K, s, remaining.copy(), start,
                                     more_pairs if not models else None, say, timer, names,
                                     focal, focal_start, view_camera, known_cameras)
        if model.registered.sum() < s.min_model_views:
            if not models:
                raise ReconstructionError("no_model", _first_model_lost(
                    model, start[0], left_out, names, s, calibrated=focal is None),
                    verified_pairs=len(pairs))
            reasons.update((v, why) for v, why in left_out.items() if remaining[v])
            break
        models.append(model)
        remaining &= ~model.registered
        reasons = {v: why for v, why in {**reasons, **left_out}.items() if remaining[v]}
        if remaining.any():
            say(f"a model of {plural(int(model.registered.sum()), 'view')} is done; "
                f"{plural(int(remaining.sum()), 'view')} left for another model")
    paired = np.zeros(V, dtype=bool)
    for p in pairs:
        paired[[p.i, p.j]] = True
    for v in np.flatnonzero(remaining):
        if not paired[v]:  # whatever else was said, this is why
            reasons[int(v)] = ("no verified pair with any other view: does it overlap the "
                               "others?")
        reasons.setdefault(int(v), "no verified pair with the views left")
    models.sort(key=lambda m: -int(m.registered.sum()))
    return models, reasons, timer.seconds
