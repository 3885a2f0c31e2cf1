"""Features: detection and matching between two images (:mod:`scene3D.features.matching`).

This package replaces the module ``scene3D.features`` and re-exports its public names.
"""

from .matching import (
    FEATURE_MODES,
    ImageFeatures,
    Matches,
    check_image,
    create_detector,
    detect_features,
    detect_keypoints,
    find_matches,
    image_features,
    match_descriptors,
    match_features,
    normalize_feature_mode,
    require_real_number,
    require_whole_number,
    resolve_feature_mode,
    surf_available,
    to_gray,
    track_flow,
)

__all__ = [
    "FEATURE_MODES", "ImageFeatures", "Matches", "check_image", "create_detector",
    "detect_features", "detect_keypoints", "find_matches", "image_features", "match_descriptors",
    "match_features", "normalize_feature_mode", "require_real_number", "require_whole_number",
    "resolve_feature_mode", "surf_available", "to_gray", "track_flow",
]
