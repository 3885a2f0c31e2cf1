"""What the two-view stages measure about a pose, in three small groups of
:class:`scene3D.twoview.results.TwoViewGeometry`: the focal lengths the inliers call for
(:class:`TwoViewFocal`), the pose's and the points' uncertainty
(:class:`TwoViewUncertainty`) and what the trust checks measured (:class:`TwoViewChecks`).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from ..geometry.conventions import FloatArray
from ..optim.uncertainty import PoseUncertainty
from .focal_fit import FocalFit


@dataclass(frozen=True)
class TwoViewFocal:
    """The focal lengths the inliers call for (:mod:`scene3D.twoview.focal_fit`).

    Attributes
    ----------
    scale, scale_sigma : float
        The focal length the inliers call for, as a multiple of the calibration's,
        and its standard deviation (:func:`scene3D.twoview.focal_fit.fit_focal_scale`;
        near 1 when the calibration fits, the sigma infinite when the pair cannot
        tell).
    ratio, ratio_sigma : float
        Image 2's focal length over image 1's that the inliers call for, with the
        calibration's geometric mean kept (:func:`scene3D.twoview.focal_fit.fit_focal_ratio`;
        near 1 when one calibration fits both photos), and its standard deviation.
    """

    scale: float = 1.0
    scale_sigma: float = float("inf")
    ratio: float = 1.0
    ratio_sigma: float = float("inf")

    @classmethod
    def from_fits(cls, scale: FocalFit, ratio: FocalFit) -> TwoViewFocal:
        """The group from the two fits, their log-scale sigmas made sigmas of the values.

        Parameters
        ----------
        scale : FocalFit
            The fit of the focal length's scale
            (:func:`scene3D.twoview.focal_fit.fit_focal_scale`).
        ratio : FocalFit
            The fit of image 2's focal length over image 1's
            (:func:`scene3D.twoview.focal_fit.fit_focal_ratio`).

        Returns
        -------
        TwoViewFocal
        """
        return cls(scale=scale.scale, scale_sigma=scale.scale * scale.sigma_log,
                   ratio=ratio.scale, ratio_sigma=ratio.scale * ratio.sigma_log)


@dataclass(frozen=True)
class TwoViewUncertainty:
    """How well the matches determine the pose and the points
    (:mod:`scene3D.optim.uncertainty`).

    Attributes
    ----------
    pose_covariance : (5, 5) float64
        First-order covariance of the pose (radians^2) in the parametrisation of
        :mod:`scene3D.optim.uncertainty`: rows 0-2 the rotation vector ``w`` of
        ``R <- exp([w]x) R`` (camera-2 frame), rows 3-4 the step of ``t`` along the
        rows of ``tangent_basis(t)`` (:attr:`TwoViewGeometry.pose_uncertainty` has both).
        Infinite when the matches do not determine the pose.
    rotation_sigma_deg, translation_sigma_deg : float
        1-sigma angles of the rotation and of the translation direction along their
        worst axes (square roots of the largest eigenvalues of the covariance's
        rotation and direction blocks), in degrees.
    noise_sigma_px : float
        Robust standard deviation of the keypoint noise, per coordinate, measured on
        the inliers (:func:`scene3D.twoview.essential_fit.noise_sigma_px`).
    noise_cut_share : float
        Share of the matches that fit the pose which the inlier threshold cut off
        (:func:`scene3D.optim.uncertainty.truncated_noise`; the covariance allows for it).
    depth_sigmas : (N,) float64
        1-sigma depth of each point in camera 1, in units of the baseline, from the
        pose covariance and the keypoint noise (:func:`scene3D.optim.uncertainty.depth_sigmas`);
        divide by ``points3d[:, 2]`` for a relative uncertainty.
    """

    pose_covariance: FloatArray = field(default_factory=lambda: np.full((5, 5), np.inf))
    rotation_sigma_deg: float = float("inf")
    translation_sigma_deg: float = float("inf")
    noise_sigma_px: float = float("nan")
    noise_cut_share: float = 0.0
    depth_sigmas: FloatArray = field(default_factory=lambda: np.zeros(0))

    @classmethod
    def from_pose(cls, pose: PoseUncertainty, depth_sigmas: FloatArray) -> TwoViewUncertainty:
        """The group from the pose's uncertainty and the points' depth sigmas.

        Parameters
        ----------
        pose : PoseUncertainty
            The pose's covariance, keypoint noise and the share the threshold cut.
        depth_sigmas : (N,) ndarray
            1-sigma depth of each point in camera 1, in units of the baseline.

        Returns
        -------
        TwoViewUncertainty
        """
        return cls(pose_covariance=pose.covariance, rotation_sigma_deg=pose.rotation_sigma_deg,
                   translation_sigma_deg=pose.translation_sigma_deg,
                   noise_sigma_px=pose.noise_sigma_px, noise_cut_share=pose.noise_cut_share,
                   depth_sigmas=depth_sigmas)


@dataclass(frozen=True)
class TwoViewChecks:
    """What the trust checks measured (:mod:`scene3D.twoview.trust`); the verdict is the
    result's ``trusted`` and ``warnings``.

    Attributes
    ----------
    homography_inlier_ratio : float
        Homography inliers / essential inliers (near 1: planar scene or no baseline).
    robust_starts : int
        Robust estimations of E run (:func:`scene3D.twoview.essential_fit.fit_essential`); when
        the best pose was not found twice in ``TwoViewSettings.max_starts`` of them
        and their optima lie more than ``TwoViewSettings.restart_agreement_deg``
        apart (found twice: more than ``TwoViewSettings.uncertainty_limit_deg``), outside
        the covariance's region, the result is untrusted.
    robust_spread_deg : float
        How far the other starts' optima lie from the chosen one
        (:attr:`scene3D.twoview.essential_fit.EssentialFit.spread_deg`; 0 when they all agree).
    behind_share : float
        Share of the inliers whose point lies behind a camera by more than the noise
        explains, at the scene's parallax
        (:func:`scene3D.geometry.triangulation.behind_at_scene_parallax`): wrong matches near
        their epipolar lines (``TwoViewSettings.max_behind_share``).
    flow_gain : float
        How much more of the dense optical flow between the images the pose refined on
        the flow explains than this pose (:attr:`scene3D.twoview.flow_check.FlowCheck.gain`; near
        0 when the flow agrees). NaN when the check did not run: no second image
        (:func:`scene3D.twoview.check_against_flow`), a pose already untrusted, or too
        little texture.
    distortion_k : float
        The radial lens distortion the matches call for, as the coefficient of the
        division model (:mod:`scene3D.twoview.distortion_fit`; 0: none, negative: barrel).
        NaN when the check did not run: a pose already untrusted, or
        ``check_distortion`` off (as in the self-calibration).
    distortion_pose_shift_deg : float
        How far the pose refined with that distortion lies from this one, in degrees
        (:func:`scene3D.geometry.pose_angle_deg`;
        :func:`scene3D.twoview.trust.distortion_warning`). NaN when not checked.
    """

    homography_inlier_ratio: float = 0.0
    robust_starts: int = 1
    robust_spread_deg: float = 0.0
    behind_share: float = 0.0
    flow_gain: float = float("nan")
    distortion_k: float = float("nan")
    distortion_pose_shift_deg: float = float("nan")
