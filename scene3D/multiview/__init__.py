"""Incremental structure from motion over many views of one calibrated camera.

The book ends with "repeat the procedure for different image pairs" and names
bundle adjustment as the missing step. One module per stage, in pipeline order:

- :mod:`~scene3D.multiview.features`: features once per image (a task per image);
- :mod:`~scene3D.multiview.retrieval`: the collection's visual vocabulary, a VLAD
  vector per view, views ranked by similarity;
- :mod:`~scene3D.multiview.pairs`: which pairs to match (retrieval, sequential, all,
  auto);
- :mod:`~scene3D.multiview.matching`: matching through visual words and essential-
  matrix verification (a task per pair);
- :mod:`~scene3D.multiview.tracks`: verified matches chained into tracks;
- :mod:`~scene3D.multiview.points`: many tracks triangulated at once;
- :mod:`~scene3D.multiview.weights`: how precisely each keypoint is located (its
  size), the weights of bundle adjustment;
- :mod:`~scene3D.multiview.mapper`: the incremental mapper's stages, several models;
- :mod:`~scene3D.multiview.state`: a growing model: registration, triangulation,
  re-triangulation, the consistency check;
- :mod:`~scene3D.multiview.adjustment`: its local and global bundle adjustments and the
  focal-length tests;
- :mod:`~scene3D.multiview.focal`: without a calibration, one focal length for all
  views (the start pair self-calibrated, then refined in the global adjustments);
- :mod:`~scene3D.multiview.lens`: one camera's lens distortion, found from a model;
- :mod:`~scene3D.multiview.cameras`: photos of several cameras (sizes, zooms), each
  with its own focal length and lens;
- :mod:`~scene3D.multiview.camera_passes`: their views reconstructed again with the
  cameras the largest model calls for;
- :mod:`~scene3D.multiview.checks`: the model against its pairs' own geometry;
- :mod:`~scene3D.multiview.view_data`, :mod:`~scene3D.multiview.sfm_model`,
  :mod:`~scene3D.multiview.models`: the data (features and pairs, one model, the result);
- :mod:`~scene3D.multiview.inputs`: the photos' default priors and the checks on them;
- :mod:`~scene3D.multiview.results`: the result in the input order;
- :mod:`~scene3D.multiview.pipeline`: :func:`reconstruct_views`, the stages in order;
- :mod:`~scene3D.multiview.video`: the frames of a video worth reconstructing (sharp,
  and far enough apart), :func:`select_frames`.

The bundle adjustment itself is :mod:`scene3D.optim.bundle` (on :mod:`scene3D.optim.schur`).

Frames: each model's world is the camera frame of the first view of its initial
pair, poses world-to-camera ``x_cam = R X + t``; the scale is that of the initial
pair (unit baseline) and is otherwise arbitrary.
"""

from .checks import check_model
from .features import extract_features, view_features
from .focal import FocalSettings
from .mapper import reconstruct_models
from .matching import match_views, verify_pair
from .models import (
    CameraIntrinsics,
    FocalEstimate,
    ModelCheck,
    MultiViewReconstruction,
    PairMatches,
    SfMModel,
    SfMSettings,
    ViewFeatures,
)
from .pairs import PAIR_MODES, select_pairs
from .pipeline import image_sources, reconstruct_views
from .retrieval import Vocabulary, describe_view, similarity_ranking, train_vocabulary
from .tracks import Tracks, build_tracks
from .video import FrameChoice, VideoFrames, select_frames

__all__ = [
    "PAIR_MODES",
    "CameraIntrinsics",
    "FocalEstimate",
    "FocalSettings",
    "FrameChoice",
    "ModelCheck",
    "MultiViewReconstruction",
    "PairMatches",
    "SfMModel",
    "SfMSettings",
    "Tracks",
    "VideoFrames",
    "ViewFeatures",
    "Vocabulary",
    "build_tracks",
    "check_model",
    "describe_view",
    "extract_features",
    "image_sources",
    "match_views",
    "reconstruct_models",
    "reconstruct_views",
    "select_frames",
    "select_pairs",
    "similarity_ranking",
    "train_vocabulary",
    "verify_pair",
    "view_features",
]
