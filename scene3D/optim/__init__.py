"""Least squares: Levenberg-Marquardt refinements, bundle adjustment, first-order covariances.

- :mod:`scene3D.optim.parametrisation`: the pose parametrisation (the step the
  refinements take, and a pose error in its coordinates);
- :mod:`scene3D.optim.uncertainty`: sandwich covariances, the pose's uncertainty and its
  chi-square bounds;
- :mod:`scene3D.optim.point_uncertainty`: the covariance and depth uncertainty of
  triangulated points;
- :mod:`scene3D.optim.least_squares`: the robust losses, the scaled normal equations and the
  Levenberg-Marquardt loop every solver here shares;
- :mod:`scene3D.optim.refinement`: the robust Sampson refinement of a two-view pose (alone or
  with one more unknown) and its covariance;
- :mod:`scene3D.optim.schur`: the sparse normal equations both bundle adjustments solve
  (the Schur products in :mod:`scene3D.optim.schur_products`);
- :mod:`scene3D.optim.bundle_two_view`: the bundle adjustment of two views;
- :mod:`scene3D.optim.bundle`: the bundle adjustment of many, optionally with one shared
  focal length.

Frames as in :mod:`scene3D.geometry`.
"""

from .bundle import (
    FocalAdjustment,
    Observations,
    bundle_adjust,
    bundle_adjust_focal,
    focal_uncertainty,
    reprojection_jacobians,
    reprojection_residuals,
    whitened_residuals,
)
from .bundle_two_view import bundle_adjust_two_view
from .least_squares import (
    LOSSES,
    damped_steps,
    levenberg_marquardt,
    reweighting,
    robust_cost,
    robust_covariance,
    robust_loss,
    robust_scaling,
)
from .parametrisation import (
    pose_error_coordinates,
    rotation_vector,
    tangent_basis,
    update_pose,
)
from .point_uncertainty import depth_sigmas, point_covariances
from .refinement import (
    pose_intrinsics_sensitivity,
    refine_pose_and_parameter,
    refine_relative_pose,
    relative_pose_covariance,
    sampson_residuals,
)
from .schur import (
    NormalEquations,
    global_information,
    normal_equations,
    solve_damped,
    solve_damped_global,
)
from .schur_products import SPARSE_SCHUR_UNKNOWNS, pairs_within_groups, schur_product
from .uncertainty import (
    CHI2_90,
    CHI2_99_POSE,
    PoseUncertainty,
    TruncatedNoise,
    angular_bound_deg,
    largest_sigma_deg,
    marginal_covariance,
    nuisance_sensitivity,
    pose_difference_chi2,
    pose_error_chi2,
    sandwich_covariance,
    truncated_noise,
)

__all__ = [
    "CHI2_90", "CHI2_99_POSE", "FocalAdjustment", "LOSSES", "NormalEquations", "Observations",
    "PoseUncertainty", "SPARSE_SCHUR_UNKNOWNS", "TruncatedNoise", "angular_bound_deg",
    "bundle_adjust", "bundle_adjust_focal", "bundle_adjust_two_view", "damped_steps",
    "depth_sigmas", "focal_uncertainty", "global_information", "largest_sigma_deg",
    "levenberg_marquardt", "marginal_covariance", "normal_equations", "nuisance_sensitivity",
    "pairs_within_groups", "point_covariances", "pose_difference_chi2", "pose_error_chi2",
    "pose_error_coordinates", "pose_intrinsics_sensitivity", "refine_pose_and_parameter",
    "refine_relative_pose", "relative_pose_covariance", "reprojection_jacobians",
    "reprojection_residuals", "reweighting", "robust_cost", "robust_covariance", "robust_loss",
    "robust_scaling", "rotation_vector", "sampson_residuals", "sandwich_covariance",
    "schur_product", "solve_damped", "solve_damped_global", "tangent_basis", "truncated_noise",
    "update_pose", "whitened_residuals",
]
