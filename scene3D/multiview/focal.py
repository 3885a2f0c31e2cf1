"""One focal length for a collection of photos without a calibration file.

The camera model is that of :mod:`scene3D.geometry.intrinsics_prior`: one focal length
(square pixels), the principal point at the image centre, no distortion. The focal
length is found in two steps:

1. **The start pair** (:func:`self_calibrated_start`). Under the prior's focal length
   (EXIF, or 1.2 times the longer side) no pair may look trustworthy: the two-view
   check sees that the matches call for another focal length. So the pair with most
   verified matches is self-calibrated (:func:`scene3D.selfcalibration.self_calibrate_pair`;
   when its photos do not determine the focal length or the result is untrusted, the
   next, up to :attr:`FocalSettings.start_candidates` pairs, the surest kept), the
   start pair is chosen under that focal length as with a calibration
   (:func:`scene3D.multiview.mapper.initial_pair`), and when it is another pair, that
   pair is self-calibrated too, from the first one's value; the mapping starts from
   its focal length. When no pair is trusted under it, a self-calibrated pair whose
   own geometry is trusted starts.
2. **The bundle adjustments.** Every global adjustment of a model of three views or
   more refines one focal length shared by all views
   (:func:`scene3D.optim.bundle.bundle_adjust_focal`: ``log f`` a global unknown, the
   principal point held), with the prior as a weak term
   ``(log f - log f_prior) / sigma_log``; the local adjustments hold it. Registration,
   triangulation and the checks use the latest value.

How sure (:func:`focal_estimate`): the adjustment's covariance of ``log f``, cameras
and points marginalised, describes the noise of the observations; the guessed
principal point adds a share (the estimate's response to the principal point moved by
:attr:`FocalSettings.principal_point_sigma` of the longer side), as for a pair, and so
does the spread of the focal length over the views (a grouped jackknife: the model
adjusted again without each quarter, or half, of its views), which sees what the noise does not:
views that call for different focal lengths (docs/benchmarks.md, "The focal length's
spread over the views"). When
the views alone know the focal length less well than the prior (views that hardly
rotate, optical axes that meet in one point), the prior's value is kept, the model is
adjusted once more under it, and the estimate says so and is untrusted.
"""

from __future__ import annotations

import logging
import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass

import numpy as np

from ..errors import ReconstructionError
from ..geometry.camera import with_focal
from ..geometry.conventions import FloatArray
from ..optim.bundle import FocalAdjustment
from ..selfcalibration import SelfCalibration, self_calibrate_pair
from ..twoview import TwoViewGeometry
from .sfm_model import FocalEstimate
from .view_data import PairMatches, ViewFeatures

logger = logging.getLogger(__name__)


@dataclass(frozen=True)
class FocalSettings:
    """The prior of the focal length and the choices of its refinement.

    Attributes
    ----------
    prior_focal_px : float
        The prior's focal length at the working size
        (:class:`scene3D.geometry.intrinsics_prior.FocalPrior`, scaled).
    prior_sigma_log : float
        Its standard deviation in ``log f``.
    prior_source : str
        ``"exif"`` or ``"prior"``.
    principal_point_sigma : float
        Assumed standard deviation of the true principal point from the image centre,
        as a fraction of the longer side (as
        :attr:`scene3D.selfcalibration.SelfCalibrationSettings.principal_point_sigma`).
    max_trusted_sigma_log : float
        A focal length known to worse than this from the views is untrusted.
    min_views : int
        Global adjustments of models with fewer views hold the focal length (the start
        pair's self-calibration stands until then).
    start_candidates : int
        At most this many pairs (those with most verified matches, in that order) are
        self-calibrated for the start, until one determines its focal length and is
        trusted.
    """

    prior_focal_px: float
    prior_sigma_log: float
    prior_source: str = "prior"
    principal_point_sigma: float = 0.01
    max_trusted_sigma_log: float = 0.1
    min_views: int = 3
    start_candidates: int = 3

    def __post_init__(self) -> None:
        if self.prior_source not in ("exif", "prior"):
            raise ValueError(f"`prior_source` must be 'exif' or 'prior', got "
                             f"{self.prior_source!r}")
        if not (math.isfinite(self.prior_focal_px) and self.prior_focal_px > 0
                and self.prior_sigma_log > 0):
            raise ValueError(f"the focal prior must be positive, got {self.prior_focal_px} px "
                             f"+-{self.prior_sigma_log} (log)")


def _self_calibrate(features: Sequence[ViewFeatures], pair: PairMatches, K: FloatArray,
                    settings: FocalSettings) -> SelfCalibration:
    return self_calibrate_pair(features[pair.i].keypoints[pair.idx_i],
                               features[pair.j].keypoints[pair.idx_j], K,
                               settings.prior_sigma_log, settings.prior_source)


def self_calibrated_start(
    features: Sequence[ViewFeatures], pairs: Sequence[PairMatches], K: FloatArray,
    settings: FocalSettings,
    choose_start: Callable[[Sequence[ViewFeatures], Sequence[PairMatches], FloatArray],
                           tuple[PairMatches, TwoViewGeometry] | str],
) -> tuple[tuple[PairMatches, TwoViewGeometry] | str, FloatArray, FocalEstimate]:
    """Step 1 of the module docstring: the start pair and the ``K`` the mapping starts with.

    Parameters
    ----------
    features, pairs
        The views and their verified pairs (the mapper's).
    K : (3, 3)
        The prior's intrinsics at the working size (centred principal point).
    settings : FocalSettings
    choose_start : callable
        How the mapper chooses its start pair under a ``K``
        (:func:`scene3D.multiview.mapper.initial_pair`).

    Returns
    -------
    start : (PairMatches, TwoViewGeometry) or str
        As :func:`scene3D.multiview.mapper.initial_pair` returns it, under ``K_start``.
    K_start : (3, 3)
    focal_start : FocalEstimate
        Where the focal length starts: the self-calibrated pair's (or the prior's, when
        no pair self-calibrates); a model too small to refine it keeps this.
    """
    ranked = sorted(pairs, key=lambda p: (-p.num_inliers, p.i, p.j))
    K = np.asarray(K, np.float64)
    tried: list[tuple[PairMatches, SelfCalibration]] = []
    for candidate in ranked[:settings.start_candidates]:
        try:
            tried.append((candidate, _self_calibrate(features, candidate, K, settings)))
        except ReconstructionError as exc:
            logger.debug("views %d-%d do not self-calibrate: %s", candidate.i, candidate.j, exc)
            continue
        if tried[-1][1].determined and tried[-1][1].trusted:
            break
    # The first pair that determines its focal length and is trusted; else the surest.
    pair, calibration = min(tried, key=lambda pc: (not (pc[1].determined and pc[1].trusted),
                                                   pc[1].data_sigma_log)) if tried else (None,
                                                                                        None)
    K_start = K if calibration is None else calibration.K
    start = choose_start(features, pairs, K_start)
    if isinstance(start, str):
        # No pair is trusted under that focal length: a self-calibrated pair whose own
        # geometry is trusted (under its own focal length) can start.
        for candidate, other in tried:
            if other.geometry.trusted:
                return ((candidate, other.geometry), other.K,
                        start_estimate(other, settings, candidate))
    elif pair is not None and (start[0].i, start[0].j) != (pair.i, pair.j):
        # A pair tried above from the same focal length would give the same again (the
        # search is deterministic): reuse it rather than pay a second search.
        again = next((other for candidate, other in tried
                      if (candidate.i, candidate.j) == (start[0].i, start[0].j)
                      and abs(math.log(K_start[0, 0] / K[0, 0])) < 1e-12), None)
        if again is None:
            try:
                again = _self_calibrate(features, start[0], K_start, settings)
            except ReconstructionError:
                again = None
        if again is not None and again.geometry.trusted:
            start, calibration, pair, K_start = (start[0], again.geometry), again, start[0], again.K
    return start, K_start, start_estimate(calibration, settings, pair)


def start_estimate(calibration: SelfCalibration | None, settings: FocalSettings,
                   pair: PairMatches | None) -> FocalEstimate:
    """The focal length a pair's self-calibration gives (the prior's without one), as a
    :class:`FocalEstimate`: where the mapping starts, and what a model too small to
    refine its focal length keeps.

    Parameters
    ----------
    calibration : SelfCalibration or None
        The start pair's self-calibration; None when no pair self-calibrated.
    settings : FocalSettings
        The focal prior (``prior_focal_px``, ``prior_sigma_log``) and trust limits.
    pair : PairMatches or None
        The pair that was self-calibrated.

    Returns
    -------
    FocalEstimate
    """
    if calibration is None:
        sigma = settings.prior_sigma_log
        return FocalEstimate(
            settings.prior_focal_px, settings.prior_focal_px * sigma, settings.prior_source,
            False, math.inf, 0.0, settings.prior_focal_px, math.inf, settings.prior_focal_px,
            sigma, settings.prior_focal_px, None,
            ("no pair self-calibrated: the focal length is the prior's",),
            sigma <= settings.max_trusted_sigma_log)
    return FocalEstimate(
        calibration.focal_px, calibration.focal_sigma_px, calibration.source,
        calibration.determined, math.inf, calibration.uncertainty.principal_point,
        calibration.data_focal_px, calibration.data_sigma_log, settings.prior_focal_px,
        settings.prior_sigma_log, calibration.focal_px,
        None if pair is None else (pair.i, pair.j), calibration.warnings, calibration.trusted)


def focal_estimate(adjustment: FocalAdjustment, settings: FocalSettings,
                   start: FocalEstimate, jackknife_sigma_log: float = 0.0) -> FocalEstimate:
    """What a model's final adjustment says of its focal length (see the module docstring).

    ``adjustment.sigma_log`` includes the prior; the views' own information is what is
    left without it, and their standard deviation adds the principal point's share and
    ``jackknife_sigma_log``, the spread of ``log f`` over the views
    (:meth:`scene3D.multiview.state.GrowingModel.focal_jackknife_sigma_log`).

    Parameters
    ----------
    adjustment : FocalAdjustment
        The model's final adjustment of its focal length (px) and ``sigma_log``.
    settings : FocalSettings
        The focal prior and trust limits.
    start : FocalEstimate
        Where the model started (:func:`start_estimate`).
    jackknife_sigma_log : float, default 0.0
        Spread of ``log f`` over the views, added to the data's standard deviation.

    Returns
    -------
    FocalEstimate
    """
    prior_sigma = settings.prior_sigma_log
    data_information = 1.0 / adjustment.sigma_log**2 - 1.0 / prior_sigma**2
    data_sigma = (math.hypot(1.0 / math.sqrt(data_information),
                             adjustment.principal_point_sigma_log, jackknife_sigma_log)
                  if data_information > 0 else math.inf)
    f_data, f_prior = adjustment.focal_px, settings.prior_focal_px
    determined = data_sigma <= prior_sigma
    warnings: list[str] = []
    if determined:
        focal = f_data
        sigma_log = math.hypot(adjustment.sigma_log, adjustment.principal_point_sigma_log,
                               jackknife_sigma_log)
        source = f"{settings.prior_source}+refined"
    else:
        focal, sigma_log, source = f_prior, prior_sigma, settings.prior_source
        rests_on = ("the EXIF value" if settings.prior_source == "exif" else
                    "the default prior (1.2 x the longer side)")
        warnings.append(f"the views do not determine the focal length better than {rests_on} "
                        f"(they fit {f_data:.1f} px +-{min(data_sigma, 9.99):.0%}): kept it")
    disagree = settings.prior_source == "exif" and abs(math.log(f_data / f_prior)) > 3.0 * \
        math.hypot(data_sigma, prior_sigma)
    if disagree:
        warnings.append(f"the views call for a focal length {f_data / f_prior:.2f} times the "
                        "EXIF one: cropped or resized photos, digital zoom, or matches that "
                        "mislead?")
    if sigma_log > settings.max_trusted_sigma_log:
        warnings.append(f"the focal length ({focal:.1f} px) is known only to "
                        f"+-{sigma_log:.0%}: the cameras may be off")
    trusted = determined and not disagree and sigma_log <= settings.max_trusted_sigma_log
    return FocalEstimate(
        focal_px=float(focal), sigma_px=float(focal * sigma_log), source=source,
        determined=determined, adjustment_sigma_log=adjustment.sigma_log,
        principal_point_sigma_log=adjustment.principal_point_sigma_log,
        data_focal_px=float(f_data), data_sigma_log=float(data_sigma),
        prior_focal_px=float(f_prior), prior_sigma_log=prior_sigma,
        start_focal_px=start.start_focal_px, start_pair=start.start_pair,
        warnings=tuple(warnings), trusted=trusted,
        jackknife_sigma_log=float(jackknife_sigma_log))


def prior_intrinsics(K: FloatArray, settings: FocalSettings) -> FloatArray:
    """``K`` with the prior's focal length (the principal point kept).

    Parameters
    ----------
    K : (3, 3) array_like
        Intrinsics whose principal point is kept.
    settings : FocalSettings
        Gives ``prior_focal_px``.

    Returns
    -------
    (3, 3) float64 ndarray
    """
    return with_focal(K, settings.prior_focal_px)


def longer_side_px(K: FloatArray) -> float:
    """The longer side of the working images, from ``K``'s centred principal point.

    Parameters
    ----------
    K : (3, 3) array_like
        Intrinsics with the principal point at the image centre (OpenCV pixels).

    Returns
    -------
    float
        The longer image side in px.
    """
    return 2.0 * max(float(K[0, 2]), float(K[1, 2])) + 1.0
