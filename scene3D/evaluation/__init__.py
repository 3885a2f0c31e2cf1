"""Evaluation: errors against ground truth, and synthetic scenes with known geometry.

- :mod:`scene3D.evaluation.poses`: pose errors, AUC, paired bootstrap;
- :mod:`scene3D.evaluation.pairs`: a dataset's pairs against its ground truth
  (``scene3d evaluate``);
- :mod:`scene3D.evaluation.synthetic`: rendered scenes and boards with known geometry;
- :mod:`scene3D.evaluation.camera_variants`: photos of one camera made into several.

This package replaces the module ``scene3D.evaluation`` and re-exports its public names.
"""

from .poses import (
    CameraSetError,
    PoseError,
    angle_between_deg,
    as_matrix,
    camera_set_error,
    paired_auc_difference,
    pose_auc,
    relative_pose_error,
    rotation_error_deg,
    sigma_calibration,
    similarity_transform,
    summarize_pose_errors,
)
from .synthetic import (
    Rectangle,
    asymmetric_camera,
    asymmetric_pose,
    box_scene,
    lens_photo,
    orbit_poses,
    orbit_scene,
    random_points,
    render_board,
    render_circles_board,
    render_planes,
    texture,
)

__all__ = [
    "CameraSetError", "PoseError", "Rectangle", "angle_between_deg", "as_matrix",
    "asymmetric_camera", "asymmetric_pose", "box_scene", "camera_set_error", "lens_photo",
    "orbit_poses", "orbit_scene", "paired_auc_difference", "pose_auc", "random_points",
    "relative_pose_error", "render_board", "render_circles_board", "render_planes",
    "rotation_error_deg", "sigma_calibration", "similarity_transform", "summarize_pose_errors",
    "texture",
]
