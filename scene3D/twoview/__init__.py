"""Two-view reconstruction from matches: E, pose, triangulation, uncertainty and trust.

The pipeline (book chapter 4, done right):

1. essential matrix from calibrated points (5-point, USAC), then a local
   optimisation of the pose on its inliers (robust Sampson refinement),
   restarted until the best fit is found twice
   (:func:`scene3D.twoview.essential_fit.fit_essential`),
2. model selection: a pure rotation (no baseline) is refused when a rotation
   homography explains the matches as well as the essential matrix
   (:func:`scene3D.twoview.degeneracy.motion_model_choice`); a planar scene is refused
   unless matches off the plane rule out the other pose a plane allows,
3. pose by cheirality over all inliers; ``F = K^-T E K^-1`` for epipolar lines,
4. triangulation, keeping points in front of both cameras with small
   reprojection error and enough parallax,
5. the pose's first-order covariance (:func:`scene3D.optim.refinement.relative_pose_covariance`,
   parametrisation in :mod:`scene3D.optim.uncertainty`), with the pull of the inliers that
   lie behind the cameras (:func:`scene3D.twoview.core.pose_covariance`), and each
   point's depth uncertainty,
6. trust (:func:`trust_warnings`): a pose is untrusted when its uncertainty is too
   large for the purpose (``TwoViewSettings.uncertainty_sigmas`` standard
   deviations beyond ``uncertainty_limit_deg``), or when something the covariance
   cannot see is at work: restarts that end at distinct optima, a focal length
   that does not fit the calibration (:func:`check_focal_length`), too few inliers
   for the covariance to be estimated or for wrong matches not to agree by chance;
   and, for a pose that passed all that, a lens distortion the calibration leaves out
   (:func:`check_distortion`): the pose refined with one radial distortion lies more
   than twice the limit away,
7. with both images at hand, the dense optical flow between them
   (:func:`check_against_flow`): sparse matches on repeated texture can agree on a
   wrong pose that the flow does not follow.

Frames: points are in the camera-1 frame, ``x_cam2 = R x_cam1 + t``, ``|t| = 1``
(the scale is unknown).
"""

from .core import (
    check_against_flow,
    reconstruct_from_matches,
    reconstruct_two_view,
    require_enough_matches,
    sample_colors,
)
from .degeneracy import is_rotation_homography, off_plane_evidence, plane_poses
from .measurements import TwoViewChecks, TwoViewFocal, TwoViewUncertainty
from .results import TwoViewGeometry, TwoViewReconstruction, TwoViewSettings
from .trust import check_distortion, check_focal_length, rival_chi2, trust_warnings

__all__ = [  # the plane checks lived here before scene3D.twoview.degeneracy
    "TwoViewChecks", "TwoViewFocal", "TwoViewGeometry", "TwoViewReconstruction",
    "TwoViewSettings", "TwoViewUncertainty", "check_against_flow",
    "check_distortion", "check_focal_length",
    "is_rotation_homography", "off_plane_evidence", "plane_poses", "reconstruct_from_matches",
    "reconstruct_two_view", "require_enough_matches", "rival_chi2", "sample_colors",
    "trust_warnings",
]
