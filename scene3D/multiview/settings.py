"""The choices and thresholds of a many-view reconstruction, and the focal test they set.

Pixels are those of the working images.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..twoview.results import TwoViewSettings
from ..twoview.trust import focal_mismatch

#: How far apart the focal lengths that different views of one scene call for lie under
#: the right calibration, as the standard deviation of their log (the adjustment's formal
#: sigma takes every observation as independent and the principal point as known):
#: :func:`refutes_calibration` adds it to that sigma.
FOCAL_SPREAD_LOG = 0.002


@dataclass(frozen=True)
class SfMSettings:
    """Choices and thresholds of the reconstruction (pixels of the working images).

    Attributes
    ----------
    threshold_px : float
        Essential-matrix inlier threshold for pair verification.
    min_pair_inliers : int
        A pair with fewer verified matches is not used.
    max_verify_iterations : int
        Robust iterations at most per pair. Matches are tried best first (PROSAC
        order by their ratio test), so a pair that overlaps is found in a few
        hundred; the cap bounds the time lost on pairs that do not overlap.
    pnp_threshold_px : float
        RANSAC reprojection threshold when registering a view.
    min_registration_inliers : int
        A view needs this many PnP inliers to be registered.
    min_confirmed_registration_inliers, min_confirmed_share : int, float
        Or this many, when its pose explains a verified pair with a registered view (at
        least ``min_pair_inliers`` of the pair's matches and this share of them, within
        ``pnp_threshold_px``; :meth:`scene3D.multiview.state.GrowingModel.pair_confirms`).
    max_reprojection_px : float
        Observations reprojecting worse are removed (after triangulation and BA).
    min_parallax_deg : float
        New points need at least this triangulation angle.
    neighbours : int
        Sequential pairs: each view is matched with this many following views.
    retrieval_neighbours : int
        Retrieval: each view is matched with its this many most similar views.
    retry_candidates : int
        A view that does not register is matched with this many further candidates
        (the next most similar views of the model) per round, ``retry_rounds`` times.
    retry_rounds : int
    vocabulary_words : int
        Visual words of the collection's vocabulary (retrieval and matching).
    probe_words : int
        Matching: a descriptor is compared with those of the other view in its this
        many nearest words.
    local_ba_views : int
        A local bundle adjustment refines the new view and its this many most
        co-visible registered views (the other views observing their points fixed).
    min_multiview_observations : int
        Bundle adjustment holds a view by the points that three or more views observe
        (they verify themselves) when it observes at least this many of them; its
        two-view points then follow the cameras instead of steering them
        (:meth:`scene3D.multiview.state.GrowingModel.adjustment_nodes`).
    global_ba_growth : float
        A global bundle adjustment (then re-triangulation) runs when the model has
        grown by this factor (in views) since the last one, and at the end.
    consistency_px : float
        The check: a verified pair whose inliers lie further than this from the model's
        epipolar geometry (median Sampson distance) contradicts the model. Correct pairs
        lie within a few tenths of a pixel of correct cameras; a pair that contradicts a
        model that is otherwise consistent is a false verification and is dropped, with
        what it attached.
    min_model_views : int
        Smallest model that is kept (a model of two views is one trusted pair).
    weight_by_size : bool
        Bundle adjustment weighs each observation by its keypoint's size (residuals
        divided by a standard deviation proportional to it,
        :mod:`scene3D.multiview.weights`), when the features carry sizes; False: all
        observations weigh the same.
    max_focal_mismatch, focal_mismatch_sigmas : float, float
        With a calibration file, a model of ``min_focal_test_views`` views or more whose
        views call for a focal length more than ``max_focal_mismatch`` from the
        calibration's (in log,
        about a fraction) and more than ``focal_mismatch_sigmas`` standard deviations
        (:func:`refutes_calibration`) refutes it.
    max_focal_refits : int
        When the largest model refutes the calibration's focal length, the views are
        reconstructed again with the focal length they call for, at most this many
        times (:attr:`MultiViewReconstruction.focal_refits`); 0: never (the model then
        fails its check).
    max_lens_passes : int
        Without a calibration and with a distorting camera model: how many times at
        most the views are reconstructed again with their keypoints undistorted by the
        lens the largest model calls for (:mod:`scene3D.multiview.lens`).
    lens_tolerance_px : float
        Another pass is made when the lens the model calls for moves an image corner
        more than this from where the current undistortion puts it.
    min_lens_shift : float
        A lens that moves no image corner more than this share of the image diagonal
        is taken as none (the keypoints stay as photographed): photos without
        distortion call for a little of it (a principal point a few pixels off the
        centre takes that shape), and undistorting by it costs focal accuracy.
    min_focal_test_views : int
        Models of fewer views are held to the two-view check's limits instead
        (``TwoViewSettings.max_focal_mismatch``, 15 %): the focal length a few views
        call for does not settle, even under the right calibration.
    min_model_points : int
        A model with fewer points is a failure, not a result: its cameras rest on
        (almost) nothing (a two-view start alone triangulates dozens);
        :attr:`MultiViewReconstruction.ok` is False.
    """

    threshold_px: float = 1.0
    min_pair_inliers: int = 30
    max_verify_iterations: int = 1000
    pnp_threshold_px: float = 3.0
    min_registration_inliers: int = 30
    min_confirmed_registration_inliers: int = 8
    min_confirmed_share: float = 0.8
    max_reprojection_px: float = 2.0
    min_parallax_deg: float = 1.5
    neighbours: int = 3
    retrieval_neighbours: int = 8
    retry_candidates: int = 5
    retry_rounds: int = 2
    vocabulary_words: int = 64
    probe_words: int = 3
    local_ba_views: int = 6
    min_multiview_observations: int = 100
    global_ba_growth: float = 1.5
    consistency_px: float = 2.0
    min_model_views: int = 2
    weight_by_size: bool = True
    max_focal_mismatch: float = 0.02
    focal_mismatch_sigmas: float = 5.0
    max_focal_refits: int = 2
    min_focal_test_views: int = 4
    max_lens_passes: int = 3
    lens_tolerance_px: float = 0.5
    min_lens_shift: float = 0.0025
    min_model_points: int = 10


def refutes_calibration(focal_scale: float, sigma_log: float, views: int,
                        s: SfMSettings) -> bool:
    """A model of ``views`` views calls for a focal length ``focal_scale`` times the
    calibration's, the standard deviation of its log ``sigma_log``
    (:attr:`ModelCheck.focal_scale`): beyond ``s.max_focal_mismatch`` in log and beyond
    ``s.focal_mismatch_sigmas`` standard deviations, ``sigma_log`` widened by
    :data:`FOCAL_SPREAD_LOG`; with fewer than ``s.min_focal_test_views`` views, beyond
    the two-view check's limits (:func:`scene3D.twoview.trust.focal_mismatch`).

    Parameters
    ----------
    focal_scale : float
        Focal length the model calls for, over the calibration's.
    sigma_log : float
        Standard deviation of ``log(focal_scale)``.
    views : int
        Number of views in the model.
    s : SfMSettings
        The limits.

    Returns
    -------
    bool
        True when the model refutes the calibration.
    """
    if views < s.min_focal_test_views:
        return focal_mismatch(focal_scale, sigma_log, TwoViewSettings())
    log_scale = abs(float(np.log(focal_scale)))
    return (log_scale > s.max_focal_mismatch
            and log_scale > s.focal_mismatch_sigmas * float(np.hypot(sigma_log,
                                                                     FOCAL_SPREAD_LOG)))
