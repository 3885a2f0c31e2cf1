"""Self-calibration of one focal length from the matches of a pair of photos.

Photos without a calibration file start from a focal length (EXIF, or a prior: see
:mod:`scene3D.geometry.intrinsics_prior`) with the principal point at the image centre. Two
views with rotation and depth determine a common focal length (H&Z section 19.5;
Bougnoux 1998): the pose and the focal length are refined together
(:func:`scene3D.twoview.focal_fit.fit_focal_scale`, through the two-view pipeline's focal
check :func:`scene3D.twoview.check_focal_length`).

What has to be iterated, and why a plain iteration is not enough:

- The essential-matrix inliers depend on ``K``: under a focal length 30 % off, the
  robust estimation keeps the matches that fit the wrong camera, and the focal fit
  on those inliers only moves part of the way. So the whole two-view estimate
  (:func:`scene3D.twoview.reconstruct_from_matches`: robust E, inliers, focal fit
  with inliers re-selected) is re-run under the refined ``K`` until the focal length
  it calls for stops changing (:func:`converge_focal`).
- That iteration is local. On scenes dominated by one plane (a facade: a plane
  fits any focal length; only the matches off it constrain it) it can settle
  where it started, off by a wide margin with a small sigma
  (docs/benchmarks.md#self-calibration-trust-that-is-not-fooled). So the starting
  point is chosen globally first (:func:`focal_profile`): the robust estimation is
  run at focal lengths spread over the prior's range, and each fit is scored over
  all matches by a robust cost whose scale follows the measured keypoint noise
  (three robust standard deviations, as the pipeline's inlier re-selection does;
  a 1 px threshold is five to ten noise sigmas at 1536 px, loose enough that
  wrong poses fitting a plane plus stray matches win). The iteration then starts
  from the best basins of that profile, and the one whose converged fit has the
  lowest cost is kept (:func:`self_calibrate_pair`).

How sure (:func:`focal_uncertainty`): the focal fit's first-order standard
deviation covers the noise of the matches given the model and the inliers, and is
far too small on its own (docs/own-photos.md#how-the-photos-refine-it). Two
shares are added. The principal point is a guess (the centre); a real camera's
lies up to about 1 % of the image away (fountain-P11's: 0.5 % and 0.8 %), which
moves the fitted focal length by up to several percent on some pairs: the fit is
repeated with it moved by :attr:`SelfCalibrationSettings.principal_point_sigma`.
And a delete-a-cell jackknife over the inliers in image 1 measures how much the
estimate rests on one part of the scene.

Two things the local sigma cannot see. The pose's own covariance is conditional on
``K``: under a focal length 20 % off it still says hundredths of a degree. So the
pose covariance reported is marginal over the intrinsics
(:func:`marginal_pose_covariance`): how the pose moves with ``log f`` and the
principal point (:func:`scene3D.optim.refinement.pose_intrinsics_sensitivity`) times their
covariance (:func:`intrinsics_covariance`) is added, and the two-view trust rule
(``TwoViewSettings.uncertainty_sigmas`` within ``uncertainty_limit_deg``) is applied
to it. And a pair can fit two focal lengths about equally well, each with its own
pose (repeated windows on a facade): a fit of the profile, or another basin, whose
cost over all matches is not significantly higher, judged with a standard error
measured over cells of the image (:func:`blocked_difference_z`), is a rival
(:func:`focal_rivals`): the focal length's sigma is widened to reach the farthest
rival, and a rival whose pose differs by more than the trust limit makes the result
untrusted.

The result is combined with the prior (inverse-variance, in ``log f``): with the
default prior the photos decide; with EXIF both count, unless they contradict each
other by more than three sigmas (an EXIF value can be plain wrong: a crop, a resized
copy, digital zoom): then photos that know the focal length to 10 % overrule it, and
the result is untrusted. When the photos know the focal length less well than the
prior (little rotation, optical axes that meet in one point: a large sigma), the
prior's value is kept and the result says so. A
focal length known to worse than
:attr:`SelfCalibrationSettings.max_trusted_sigma_log` (10 %), as when it rests on
the default prior, leaves the result untrusted; so does another basin that fits
about as well.

Frames as in :mod:`scene3D.geometry`; focal lengths are in pixels of the images the
matches come from (the working images).
"""

from .pair import CALIBRATION_SOURCES, SelfCalibration, SelfCalibrationSettings, self_calibrate_pair
from .search import FocalProfile, combine_log_normal, converge_focal, focal_profile, with_focal
from .uncertainty import (
    FocalUncertainty,
    Rival,
    blocked_difference_z,
    focal_rivals,
    focal_uncertainty,
    image_cells,
    intrinsics_covariance,
    marginal_pose_covariance,
)

__all__ = [
    "CALIBRATION_SOURCES",
    "FocalProfile",
    "FocalUncertainty",
    "Rival",
    "SelfCalibration",
    "SelfCalibrationSettings",
    "blocked_difference_z",
    "combine_log_normal",
    "converge_focal",
    "focal_profile",
    "focal_rivals",
    "focal_uncertainty",
    "image_cells",
    "intrinsics_covariance",
    "marginal_pose_covariance",
    "self_calibrate_pair",
    "with_focal",
]
