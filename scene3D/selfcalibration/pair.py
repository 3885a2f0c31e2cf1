"""The self-calibration of a pair: its settings, its result and :func:`self_calibrate_pair`
(see :mod:`scene3D.selfcalibration`)."""

from __future__ import annotations

import logging
import math
import time
from dataclasses import dataclass, replace

import numpy as np
from numpy.typing import ArrayLike

from ..errors import ReconstructionError
from ..geometry.conventions import (
    FloatArray,
    as_matrix,
    as_points2d,
    check_same_length,
    distinct_correspondences,
    require_real_number,
)
from ..optim.uncertainty import depth_sigmas, largest_sigma_deg
from ..twoview import TwoViewGeometry, TwoViewSettings, reconstruct_from_matches
from ..twoview.essential_fit import essential_cost
from ..twoview.trust import beyond_uncertainty_limit, sigmas_text
from .search import FocalProfile, combine_log_normal, converge_focal, focal_profile, with_focal
from .uncertainty import (
    FocalUncertainty,
    focal_rivals,
    focal_uncertainty,
    intrinsics_covariance,
    marginal_pose_covariance,
)

logger = logging.getLogger(__name__)


#: ``calibration_source`` values: where the focal length of the final ``K`` comes from.
CALIBRATION_SOURCES = ("file", "exif", "exif+refined", "prior", "prior+refined")


@dataclass(frozen=True)
class SelfCalibrationSettings:
    """Choices of the focal self-calibration (the two-view thresholds are in
    :class:`scene3D.twoview.TwoViewSettings`).

    Attributes
    ----------
    search_sigmas : float
        The profile spans the prior's focal length times ``exp(+-search_sigmas *
        sigma_log)``, and at least ``min_search_factor`` either way.
    min_search_factor : float
        At least this factor either way (2: an EXIF focal length can be wrong by a
        crop or a digital zoom).
    search_step : float
        Ratio between neighbouring focal lengths of the profile.
    max_candidates : int
        Basins of the profile (lowest first) from which the iteration is run.
    max_iterations, tolerance_log : int, float
        The iteration stops when the focal length changes by less than
        ``tolerance_log`` (in ``log f``), or after ``max_iterations``.
    min_noise_threshold : float
        The profile's cost threshold (three noise sigmas) is not set below this
        fraction of ``TwoViewSettings.threshold_px`` (noise-free matches).
    principal_point_sigma : float
        Assumed standard deviation of the true principal point from the image
        centre, as a fraction of the longer side.
    jackknife_cells : int
        The inliers are split into ``jackknife_cells``^2 cells of image 1 for the
        jackknife (:func:`focal_uncertainty`).
    max_trusted_sigma_log : float
        A result whose focal length is known to worse than this (standard deviation
        of ``log f``) is untrusted: the pose may be off by degrees.
    ambiguity_cost : float
        Another basin whose converged cost is within this of the best one's (in
        the units of :func:`scene3D.twoview.essential_fit.essential_cost`, where an outlier costs
        2.3) and whose focal length differs by more than three standard deviations
        makes the result ambiguous (untrusted).
    pose_principal_point : bool
        The pose's covariance includes the principal point's uncertainty
        (``principal_point_sigma``) besides the focal length's
        (:func:`marginal_pose_covariance`). It dominates the translation direction's
        sigma: a principal point 1 % of the longer side off turns the camera frame by
        about 0.6 deg whatever the resolution. False: the focal length's alone.
    rival_z : float
        A fit at a focal length more than three sigmas away whose cost over all
        matches is not higher by ``rival_z`` standard errors (blocked by the
        jackknife's cells, :func:`blocked_difference_z`; about a 2.5 % one-sided
        test) is a rival (:func:`focal_rivals`): the focal length's sigma is widened
        to reach it, and when its pose differs by more than
        ``TwoViewSettings.uncertainty_limit_deg`` the result is untrusted.
    """

    search_sigmas: float = 2.0
    min_search_factor: float = 2.0
    search_step: float = 1.15
    max_candidates: int = 3
    max_iterations: int = 8
    tolerance_log: float = 1e-3
    min_noise_threshold: float = 0.1
    principal_point_sigma: float = 0.01
    jackknife_cells: int = 3
    max_trusted_sigma_log: float = 0.1
    ambiguity_cost: float = 10.0
    pose_principal_point: bool = True
    rival_z: float = 2.0


@dataclass(frozen=True)
class SelfCalibration:
    """The focal length found for a pair, and the pair's geometry under it.

    Attributes
    ----------
    K : (3, 3) float64
        The intrinsics used in the end (working images): ``geometry`` was
        estimated with them.
    focal_px : float
        ``K[0, 0]`` (= ``K[1, 1]``).
    focal_sigma_px : float
        Its standard deviation: the fit's and the principal point's share combined
        with the prior's, or the prior's alone when the photos did not determine it;
        at least the distance (in ``log f``) to the farthest focal length the matches
        do not tell apart from it (:func:`focal_rivals`).
    source : str
        ``"exif+refined"`` / ``"prior+refined"`` (the photos determined it), or
        ``"exif"`` / ``"prior"`` (they did not; the value is the start's).
    determined : bool
        The photos determined the focal length at least as well as the prior did
        (``data_sigma_log <= start_sigma_log``), or well enough
        (``SelfCalibrationSettings.max_trusted_sigma_log``) to overrule an EXIF value
        they contradict by more than three sigmas; when not, ``K`` keeps the prior's.
    data_focal_px, data_sigma_log : float
        What the photos alone call for, and its standard deviation in ``log f``
        (``uncertainty.total``; inf when the fit could not tell).
    uncertainty : FocalUncertainty
        Its parts: the fit's, the jackknife's and the principal point's.
    start_focal_px, start_sigma_log : float
        The prior it started from.
    geometry : TwoViewGeometry
        The two-view estimate under ``K``; its ``pose_covariance``,
        ``rotation_sigma_deg``, ``translation_sigma_deg`` and ``depth_sigmas`` are
        marginal over the focal length and the principal point
        (:func:`marginal_pose_covariance`), not conditional on ``K``; its ``trusted``
        and ``warnings`` are the two-view pipeline's under ``K``.
    profile : FocalProfile
        The profile the starting basins came from.
    candidates : tuple[tuple[float, float], ...]
        ``(focal_px, cost)`` of each basin's converged fit, the chosen first.
    iterations : int
        Two-view estimates run while iterating (all basins).
    warnings : tuple[str, ...]
        Doubts about the focal length (the geometry's own are in
        ``geometry.warnings``).
    trusted : bool
        ``geometry.trusted``, and the focal length known to
        ``SelfCalibrationSettings.max_trusted_sigma_log`` (so not resting on the
        default prior alone), no other focal length fitting about as well (another
        basin, or a rival, :func:`focal_rivals`), the photos not contradicting an EXIF
        value (by more than three sigmas), and the pose certain enough for
        ``TwoViewSettings`` (``uncertainty_sigmas`` of its marginal sigmas within
        ``uncertainty_limit_deg``).
    focal_trusted : bool
        Those conditions but the first: ``trusted`` is ``geometry.trusted and
        focal_trusted``. A later check of the pose under ``K`` (the dense flow check,
        :func:`scene3D.twoview.check_against_flow`) combines with this one.
    seconds : float
        Time spent.
    """

    K: FloatArray
    focal_px: float
    focal_sigma_px: float
    source: str
    determined: bool
    data_focal_px: float
    data_sigma_log: float
    uncertainty: FocalUncertainty
    start_focal_px: float
    start_sigma_log: float
    geometry: TwoViewGeometry
    profile: FocalProfile
    candidates: tuple[tuple[float, float], ...]
    iterations: int
    warnings: tuple[str, ...] = ()
    trusted: bool = True
    focal_trusted: bool = True
    seconds: float = 0.0


def _main_doubt(uncertainty: FocalUncertainty) -> str:
    """What limits the focal length most, in words."""
    parts = {"little rotation, or optical axes that meet": uncertainty.fit,
             "it rests on one part of the scene": uncertainty.jackknife,
             "the principal point is unknown": uncertainty.principal_point}
    return max(parts, key=lambda k: parts[k] if math.isfinite(parts[k]) else math.inf)


def _search_factors(prior_sigma_log: float, s: SelfCalibrationSettings) -> FloatArray:
    half = max(s.search_sigmas * prior_sigma_log, math.log(s.min_search_factor))
    steps = max(2, math.ceil(2.0 * half / math.log(s.search_step)))
    return np.exp(np.linspace(-half, half, steps + 1))


def self_calibrate_pair(
    pts1: ArrayLike,
    pts2: ArrayLike,
    K_start: ArrayLike,
    prior_sigma_log: float,
    prior_source: str = "prior",
    settings: TwoViewSettings | None = None,
    search: SelfCalibrationSettings | None = None,
) -> SelfCalibration:
    """The focal length of a pair of photos from one camera, and the pair's geometry under it.

    Parameters
    ----------
    pts1, pts2 : (N, 2) array_like
        Matched pixels in image 1 and image 2 (working images).
    K_start : (3, 3) array_like
        The starting intrinsics of the working images: the prior's focal length and
        principal point (:class:`scene3D.geometry.intrinsics_prior.FocalPrior`, scaled to the
        working size). Only the focal length changes.
    prior_sigma_log : float
        Standard deviation of the prior's ``log f``.
    prior_source : str
        ``"exif"`` or ``"prior"``: names the result's ``source``.
    settings : TwoViewSettings, optional
        The two-view pipeline's thresholds (its ``check_distortion`` is not used: the
        distortion check does not run here).
    search : SelfCalibrationSettings, optional
        The self-calibration's.

    Returns
    -------
    SelfCalibration

    Raises
    ------
    ReconstructionError
        The pair is refused under every focal length tried (too few matches, no
        parallax, ...), with the reason found at the prior's focal length.
    ValueError
        Bad input shapes, a ``prior_source`` other than ``"exif"`` / ``"prior"``, or a
        ``prior_sigma_log`` not in (0, 10].
    """
    t0 = time.perf_counter()
    s = search or SelfCalibrationSettings()
    # The distortion check is nearly blind under a fitted focal length, which soaks up
    # most of a distortion, and would run in every round of the search (docs/trust.md).
    tv = replace(settings or TwoViewSettings(), check_distortion=False)
    if prior_source not in ("exif", "prior"):
        raise ValueError(f"`prior_source` must be 'exif' or 'prior', got {prior_source!r}")
    require_real_number(prior_sigma_log, "prior_sigma_log", 0.0, 10.0)
    p1, p2 = as_points2d(pts1, "pts1"), as_points2d(pts2, "pts2")
    check_same_length(p1, p2)
    K0 = as_matrix(K_start, (3, 3), "K_start")
    f0 = float(K0[0, 0])
    distinct = len(distinct_correspondences(p1, p2))  # counted as the two-view core does
    if distinct < tv.min_matches:
        raise ReconstructionError("too_few_matches", "too few matches between the images",
                                  matches=distinct, required=tv.min_matches)

    profile = focal_profile(p1, p2, K0, _search_factors(prior_sigma_log, s), tv.threshold_px,
                            s.min_noise_threshold * tv.threshold_px, tv.min_inliers)
    starts = [float(profile.focal_px[i]) for i in profile.basins()[:s.max_candidates]]
    if prior_source == "exif" or not starts:
        starts.append(f0)
    # Converge from each basin; basins that end at the same focal length count once.
    runs: list[tuple[float, TwoViewGeometry]] = []
    iterations, refusal = 0, None
    for start in starts:
        if any(abs(math.log(start / g.K[0, 0])) < 3 * s.tolerance_log for _, g in runs):
            continue
        try:
            geometry, rounds, converged = converge_focal(p1, p2, with_focal(K0, start), tv,
                                                         s.max_iterations, s.tolerance_log)
        except ReconstructionError as exc:
            refusal = refusal or exc
            continue
        iterations += rounds
        if not converged:
            logger.debug("focal iteration from %.1f px did not settle", start)
        if any(abs(math.log(geometry.K[0, 0] / g.K[0, 0])) < 0.005 for _, g in runs):
            continue
        runs.append((essential_cost(geometry.E, p1, p2, geometry.K, profile.threshold_px),
                     geometry))
    if not runs:
        # Say why under the prior's own focal length, as a calibrated run would.
        reconstruct_from_matches(p1, p2, K0, tv)
        raise refusal  # type: ignore[misc]
    runs.sort(key=lambda run: run[0])
    best_cost, best = runs[0]

    f_data = float(best.K[0, 0] * best.focal_scale)
    longer_side = 2.0 * max(K0[0, 2], K0[1, 2]) + 1.0  # the principal point is the centre
    uncertainty = focal_uncertainty(best, tv, s.principal_point_sigma * longer_side,
                                    s.jackknife_cells)
    sigma_data = uncertainty.total
    warnings: list[str] = []
    # The photos refine the start when they know the focal length at least as well.
    determined = sigma_data <= prior_sigma_log
    ambiguous = [g for c, g in runs[1:] if c - best_cost < s.ambiguity_cost
                 and abs(math.log(g.K[0, 0] / f_data)) > 3.0 * sigma_data]
    rivals = focal_rivals(
        p1, p2, best, f_data, sigma_data,
        [(float(f), E) for f, E in zip(profile.focal_px, profile.essentials)]
        + [(float(g.K[0, 0]), g.E) for _, g in runs[1:]],
        profile.threshold_px, s.rival_z, s.jackknife_cells)
    pose_rivals = [r for r in rivals if r.pose_difference_deg > tv.uncertainty_limit_deg]
    # Photos and EXIF that disagree beyond their sigmas: one of them is wrong. An EXIF
    # value can be wrong outright (a cropped or resized copy, digital zoom), so beyond
    # three sigmas photos that know the focal length well enough overrule it (the
    # Gaussian combination assumes neither is); the result is doubted either way.
    disagree = prior_source == "exif" and abs(math.log(f_data / f0)) > 3.0 * math.hypot(
        sigma_data, prior_sigma_log)
    if disagree and sigma_data <= s.max_trusted_sigma_log:
        determined = True
        focal, sigma, source = f_data, sigma_data, "exif+refined"
        warnings.append(
            f"the photos call for a focal length {f_data / f0:.2f} times the EXIF one "
            f"(+-{sigma_data:.0%}): cropped or resized photos, digital zoom, or matches that "
            f"mislead? Using the photos' {focal:.1f} px")
    elif determined:
        focal, sigma = combine_log_normal(f_data, sigma_data, f0, prior_sigma_log)
        source = f"{prior_source}+refined"
    else:
        focal, sigma, source = f0, prior_sigma_log, prior_source
        rests_on = ("the EXIF value" if prior_source == "exif" else
                    "the default prior (1.2 x the longer side)")
        warnings.append(f"the photos do not determine the focal length better than "
                        f"{rests_on} (they fit {f_data:.1f} px +-{min(sigma_data, 9.99):.0%}, "
                        f"{_main_doubt(uncertainty)}): kept it")
        if disagree:
            warnings.append(f"the photos call for a focal length {f_data / f0:.2f} times the "
                            "EXIF one: the EXIF value may be wrong")
    if determined and rivals:
        # The focal lengths the matches do not tell apart bound what is known of it.
        sigma = max(sigma, max(abs(math.log(r.focal_px / f_data)) for r in rivals))
    # The pose under the focal length found (the best run's, when that is within the
    # tolerance: its K is the one reported, and quoted below).
    geometry = best
    if abs(math.log(focal / best.K[0, 0])) >= s.tolerance_log:
        geometry = reconstruct_from_matches(p1, p2, with_focal(K0, focal), tv)
        iterations += 1
    if sigma > s.max_trusted_sigma_log:
        known = (f"+-{sigma:.0%}" if sigma < 0.5 else f"a factor of {math.exp(sigma):.1f}")
        warnings.append(f"the focal length ({geometry.K[0, 0]:.1f} px) is known only to {known}: "
                        "the pose may be off by degrees")
    if ambiguous:
        other = ", ".join(f"{g.K[0, 0]:.1f} px" for g in ambiguous)
        warnings.append(f"other focal lengths fit the matches about as well ({other} against "
                        f"{f_data:.1f} px): the focal length, and the pose, may be wrong")
    if pose_rivals:
        worst_rival = max(pose_rivals, key=lambda r: r.pose_difference_deg)
        warnings.append(
            f"the matches do not tell their best fit, {f_data:.1f} px, from "
            f"{worst_rival.focal_px:.1f} px "
            f"(cost difference {worst_rival.z:.1f} standard errors), whose pose differs by "
            f"{worst_rival.pose_difference_deg:.1f} deg: the focal length, and the pose, may "
            "be wrong" + (f" ({len(pose_rivals)} such focal lengths)"
                          if len(pose_rivals) > 1 else ""))
    # The pose's uncertainty with the focal length's and the principal point's added.
    weight = (0.0 if not determined or not math.isfinite(sigma_data)
              else min(1.0, (sigma / sigma_data) ** 2))
    pp_sigma = (s.principal_point_sigma * longer_side if s.pose_principal_point else 0.0)
    covariance = marginal_pose_covariance(
        geometry, intrinsics_covariance(sigma, pp_sigma, uncertainty.principal_point_shifts,
                                        weight), tv)
    geometry = replace(geometry, uncertainty=replace(
        geometry.uncertainty, pose_covariance=covariance,
        rotation_sigma_deg=largest_sigma_deg(covariance[:3, :3]),
        translation_sigma_deg=largest_sigma_deg(covariance[3:, 3:]),
        depth_sigmas=depth_sigmas(geometry.points3d, geometry.K, geometry.R, geometry.t,
                                  covariance, geometry.noise_sigma_px)))
    uncertain = beyond_uncertainty_limit(geometry.rotation_sigma_deg,
                                         geometry.translation_sigma_deg, tv)
    if uncertain:
        sigmas = sigmas_text(geometry.rotation_sigma_deg, geometry.translation_sigma_deg)
        warnings.append(
            f"uncertain pose once the focal length's and the principal point's uncertainty "
            f"is included: {sigmas}, more than {tv.uncertainty_limit_deg:g} deg at "
            f"{tv.uncertainty_sigmas:g} sigma")
    focal_trusted = (not ambiguous and not pose_rivals and not disagree and not uncertain
                     and sigma <= s.max_trusted_sigma_log)
    return SelfCalibration(
        K=geometry.K, focal_px=float(geometry.K[0, 0]), focal_sigma_px=focal * sigma,
        source=source, determined=determined, data_focal_px=f_data,
        data_sigma_log=sigma_data, uncertainty=uncertainty,
        start_focal_px=f0, start_sigma_log=prior_sigma_log, geometry=geometry,
        profile=profile, candidates=tuple((float(g.K[0, 0]), float(c)) for c, g in runs),
        iterations=iterations, warnings=tuple(warnings),
        trusted=geometry.trusted and focal_trusted, focal_trusted=focal_trusted,
        seconds=time.perf_counter() - t0)
