import logging

import cv2
import numpy as np
import pytest

from scene3D.features import (
    find_matches,
    image_features,
    match_descriptors,
    match_features,
    normalize_feature_mode,
)
from scene3D.features import matching as features


def test_modes_are_case_insensitive_and_unknown_modes_are_listed():
    assert normalize_feature_mode("sift") == "SIFT"
    assert normalize_feature_mode("FLOW") == "flow"
    with pytest.raises(ValueError, match="valid modes are SIFT, SURF, ORB, AKAZE, flow"):
        normalize_feature_mode("BRISK")


def test_ratio_and_mutual_check():
    d1 = np.array([[0, 0], [10, 0], [0, 10]], np.float32)
    # d2[0] is close to d1[0]; d2[1] is ambiguous between d1[1] and d1[2]; d2[2] is far away.
    d2 = np.array([[0.1, 0], [5, 5], [100, 100]], np.float32)
    i1, i2 = match_descriptors(d1, d2, cv2.NORM_L2, ratio=0.8)
    assert list(zip(i1, i2)) == [(0, 0)]


def _opencv_ratio_and_cross_check(d1, d2, ratio):
    """The reference: cv2.BFMatcher knnMatch + ratio test, and a full backward match."""
    matcher = cv2.BFMatcher(cv2.NORM_L2)
    backward = {m.queryIdx: m.trainIdx for m in matcher.match(d2, d1)}
    return [(m.queryIdx, m.trainIdx) for m, n in matcher.knnMatch(d1, d2, k=2)
            if m.distance < ratio * n.distance and backward[m.trainIdx] == m.queryIdx]


def test_blas_matcher_finds_exactly_the_opencv_matches(rendered_pair, monkeypatch):
    sift = cv2.SIFT_create()
    gray = [cv2.cvtColor(img, cv2.COLOR_BGR2GRAY) for img in rendered_pair[:2]]
    (_, d1), (_, d2) = (sift.detectAndCompute(g, None) for g in gray)
    expected = _opencv_ratio_and_cross_check(d1, d2, 0.8)
    assert len(expected) > 100
    assert list(zip(*match_descriptors(d1, d2, cv2.NORM_L2, 0.8))) == expected
    # Blocks of rows give the same answer as one block.
    small_blocks = features._match_l2(d1, d2, 0.8, block_rows=97)
    assert list(zip(*small_blocks)) == expected


@pytest.mark.parametrize("mode, tolerance_px", [
    ("SIFT", 0.5), ("ORB", 1.0), ("AKAZE", 0.5), ("flow", 0.1),  # ORB has no sub-pixel step
])
def test_known_shift_is_found(rendered_pair, mode, tolerance_px):
    img1 = rendered_pair[0]
    shift = np.array([6.25, -3.5])
    M = np.float32([[1, 0, shift[0]], [0, 1, shift[1]]])
    img2 = cv2.warpAffine(img1, M, (img1.shape[1], img1.shape[0]))
    m = find_matches(img1, img2, mode)
    assert len(m) > 100
    assert m.feature == mode
    d = m.pts2 - m.pts1 - shift
    assert np.median(np.linalg.norm(d, axis=1)) < tolerance_px
    assert set(m.timings_s) == {"features", "matching"}


def test_surf_falls_back_to_sift_with_one_warning(rendered_pair, caplog, monkeypatch):
    monkeypatch.setattr(features, "_warned_surf", False)
    img1, img2 = rendered_pair[:2]
    with caplog.at_level(logging.WARNING):
        m = find_matches(img1, img2, "SURF")
        find_matches(img1, img2, "surf")
    if m.feature == "SURF":  # an OpenCV build with the non-free module
        pytest.skip("this OpenCV has SURF")
    assert m.feature == "SIFT"
    assert len(m) > 100
    assert sum("SURF" in r.message for r in caplog.records) == 1


def test_features_of_different_detectors_do_not_match():
    img = np.random.default_rng(0).integers(0, 255, (120, 160), dtype=np.uint8)
    with pytest.raises(ValueError, match="cannot match ORB features with SIFT features"):
        match_features(image_features(img, "ORB"), image_features(img, "SIFT"))


@pytest.mark.parametrize("mode, width, dtype", [("SIFT", 128, np.float32),
                                                ("ORB", 32, np.uint8), ("AKAZE", 61, np.uint8)])
def test_a_blank_image_has_no_keypoints_and_an_empty_descriptor_table(mode, width, dtype):
    blank = image_features(np.full((120, 160), 128, np.uint8), mode)
    assert blank.pixels.shape == (0, 2)
    assert blank.descriptors.shape == (0, width) and blank.descriptors.dtype == dtype
    textured = image_features(np.random.default_rng(0).integers(0, 255, (120, 160), np.uint8),
                              mode)
    assert textured.descriptors.shape[1] == width and textured.descriptors.dtype == dtype
    assert len(match_features(blank, textured).pts1) == 0


def _mirror_bias_px(gray, detector):
    """Median (bias_x, bias_y) of keypoints against their twins in the mirrored images.

    A keypoint at x in an image of width W has its twin at W - 1 - x in the image
    flipped left-right; a detector that reports x + b puts the twin at W - 1 - x + b,
    so half the disagreement is the bias b (the same for y with an up-down flip).
    """
    bias = []
    for flip, axis in ((1, 0), (0, 1)):
        p = cv2.KeyPoint_convert(detector.detect(gray, None)).astype(np.float64)
        q = cv2.KeyPoint_convert(detector.detect(cv2.flip(gray, flip), None)).astype(np.float64)
        q[:, axis] = gray.shape[1 - axis] - 1 - q[:, axis]
        dist = np.linalg.norm(p[:, None, :] - q[None, :, :], axis=2)
        nearest = dist.argmin(axis=1)
        twins = dist[np.arange(len(p)), nearest] < 1.0
        assert twins.sum() > 100
        bias.append(np.median(p[twins, axis] - q[nearest[twins], axis]) / 2)
    return np.array(bias)


def test_sift_keypoints_have_no_quarter_pixel_bias(rendered_pair):
    gray = cv2.cvtColor(rendered_pair[0], cv2.COLOR_BGR2GRAY)
    # OpenCV's default SIFT reports keypoints 0.25 px right and down of where they are ...
    np.testing.assert_allclose(_mirror_bias_px(gray, cv2.SIFT_create()), 0.25, atol=0.02)
    # ... and scene3D's does not.
    detector, _, name = features.create_detector("SIFT")
    assert name == "SIFT"
    np.testing.assert_allclose(_mirror_bias_px(gray, detector), 0.0, atol=0.02)
