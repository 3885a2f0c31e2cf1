"""Geometry: the conventions, cameras, epipolar relations, poses, points and rectification.

The conventions every module of scene3D follows (pixels, frames, the epipolar constraint,
array shapes) are stated once, in :mod:`scene3D.geometry.conventions`; this package
re-exports its helpers, so ``from scene3D.geometry import skew`` works as it always did.

- :mod:`scene3D.geometry.conventions`: the conventions and small geometric helpers;
- :mod:`scene3D.geometry.camera`: ``K`` and the distortion: validation, scaling, undistortion;
- :mod:`scene3D.geometry.intrinsics_prior`: a starting ``K`` for photos without a
  calibration (EXIF focal length or a prior) and the one-camera check;
- :mod:`scene3D.geometry.epipolar`: ``F``, ``E`` and ``H``, Sampson distances, robust fits;
- :mod:`scene3D.geometry.pose`: the four decompositions of ``E`` and cheirality;
- :mod:`scene3D.geometry.triangulation`: DLT triangulation and parallax;
- :mod:`scene3D.geometry.rectification`: ``stereoRectify`` with (width, height).

Only the conventions are re-exported: the other modules are imported by their own paths
(they load OpenCV, which the conventions do not need). The geometry imports nothing above
it: :mod:`scene3D.optim` and :mod:`scene3D.io` build on it.
"""

from .conventions import (
    FloatArray,
    angle_between_deg,
    as_matrix,
    as_points2d,
    camera_centers,
    check_same_length,
    distinct_correspondences,
    image_size,
    is_real_number,
    is_whole_number,
    median,
    normalize_points,
    pose_angle_deg,
    project,
    project_with_jacobian,
    projection_matrix,
    quaternion_from_rotation,
    relative_pose,
    require_real_number,
    require_whole_number,
    rotation_about_axis,
    rotation_angle_deg,
    rotation_error_deg,
    rotation_from_quaternion,
    rotations_from_vectors,
    skew,
    skews,
    to_homogeneous,
)

__all__ = [
    "FloatArray", "angle_between_deg", "as_matrix", "as_points2d", "camera_centers",
    "check_same_length", "distinct_correspondences", "image_size", "is_real_number",
    "is_whole_number", "median",
    "normalize_points", "pose_angle_deg", "project", "project_with_jacobian", "projection_matrix",
    "quaternion_from_rotation", "relative_pose", "require_real_number", "require_whole_number",
    "rotation_about_axis", "rotation_angle_deg", "rotation_error_deg", "rotation_from_quaternion",
    "rotations_from_vectors", "skew", "skews", "to_homogeneous",
]
