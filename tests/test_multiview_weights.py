"""Observations weighed by keypoint size: the weights, the weighted adjustment, and the
mapper on synthetic views whose keypoints are located less precisely the larger they are
(as SIFT's are)."""

import cv2
import numpy as np
import pytest

from scene3D.evaluation import camera_set_error
from scene3D.geometry import project
from scene3D.multiview import (
    SfMSettings,
    ViewFeatures,
    extract_features,
    reconstruct_models,
)
from scene3D.multiview.weights import keypoint_sigma
from scene3D.optim.bundle import (
    Observations,
    bundle_adjust,
    reprojection_residuals,
    whitened_residuals,
)

from .test_multiview import K, _ring_of_cameras, _ring_views

#: Keypoint noise per coordinate, per pixel of keypoint size (SIFT on Herz-Jesus-P8: about
#: 0.02-0.03 px per px of size).
NOISE_PER_SIZE = 0.03


def _sizes(rng, n):
    """Keypoint sizes log-uniform over 1.8-30 px, as SIFT's spread over its octaves."""
    return np.exp(rng.uniform(np.log(1.8), np.log(30.0), n))


def test_sigma_is_proportional_to_the_size_with_median_one():
    sizes = np.array([2.0, 4.0, 8.0, 3.0, 12.0])
    np.testing.assert_allclose(keypoint_sigma(sizes), sizes / 4.0)
    assert np.median(keypoint_sigma(sizes)) == 1.0
    # Without a usable scale every keypoint weighs the same.
    np.testing.assert_array_equal(keypoint_sigma(np.array([2.0, 0.0, 3.0])), np.ones(3))
    np.testing.assert_array_equal(keypoint_sigma(np.array([2.0, np.nan])), np.ones(2))
    assert keypoint_sigma(np.zeros(0)).shape == (0,)


def test_whitened_residuals_divide_by_sigma():
    Rs, ts = _ring_of_cameras(3)
    X = np.array([[0.5, -0.2, 8.0], [-1.0, 0.4, 9.0]])
    view, point = np.array([0, 1, 2, 0]), np.array([0, 0, 1, 1])
    xy = np.array([project(X[p:p + 1], K, Rs[v], ts[v])[0] for v, p in zip(view, point)])
    xy += [[0.3, -0.1], [0.0, 0.2], [-0.4, 0.1], [0.1, 0.1]]
    sigma = np.array([0.5, 2.0, 1.0, 4.0])
    plain = reprojection_residuals(Rs, ts, X, Observations(view, point, xy), K)
    np.testing.assert_allclose(
        whitened_residuals(Rs, ts, X, Observations(view, point, xy, sigma), K),
        plain / sigma[:, None])
    np.testing.assert_array_equal(whitened_residuals(Rs, ts, X, Observations(view, point, xy),
                                                     K), plain)


def _scale_noise_observations(seed, views=6, points=600):
    """Views of the ring seeing random points; each observation has a size and noise of
    ``NOISE_PER_SIZE * size`` per coordinate. Returns the truth, the observations and the
    sizes."""
    rng = np.random.default_rng(seed)
    Rs, ts = _ring_of_cameras(views)
    X = rng.uniform([-3, -2, 6], [3, 2, 11], (points, 3))
    view, point, xy = [], [], []
    for v, (R, t) in enumerate(zip(Rs, ts)):
        pix = project(X, K, R, t)
        seen = np.flatnonzero(np.all((pix > 0) & (pix < [660, 490]), axis=1))
        view.append(np.full(len(seen), v))
        point.append(seen)
        xy.append(pix[seen])
    view, point, xy = np.concatenate(view), np.concatenate(point), np.vstack(xy)
    sizes = _sizes(rng, len(view))
    xy = xy + rng.normal(0, 1, xy.shape) * NOISE_PER_SIZE * sizes[:, None]
    return Rs, ts, X, view, point, xy, sizes


def test_weighting_by_size_brings_the_cameras_closer_under_scale_dependent_noise():
    """Maximum likelihood beats equal weights: over five noise draws, the adjustment that
    divides each residual by its keypoint's relative sigma ends with camera centres
    closer to the truth (both from the true cameras, fixed view 0, similarity-aligned)."""
    errors = {"equal": [], "by size": []}
    for seed in range(5):
        Rs, ts, X, view, point, xy, sizes = _scale_noise_observations(seed)
        centers_true = -np.einsum("vji,vj->vi", Rs, ts)
        for label, sigma in (("equal", None), ("by size", keypoint_sigma(sizes))):
            R, t, _ = bundle_adjust(Rs, ts, X, Observations(view, point, xy, sigma), K, 0,
                                    max_iterations=30)
            err = camera_set_error(R, -np.einsum("vji,vj->vi", R, t), Rs, centers_true)
            errors[label].append(np.median(err.center_errors))
    equal, weighted = np.mean(errors["equal"]), np.mean(errors["by size"])
    assert weighted < 0.7 * equal
    assert sum(w < e for w, e in zip(errors["by size"], errors["equal"])) >= 4


def _synthetic_views_with_sizes(seed):
    """The ring's views as keypoints with sizes and scale-dependent noise, and the verified
    pairs (every true correspondence)."""
    def observe(rng, pix):
        sizes = _sizes(rng, len(pix))
        return pix + rng.normal(0, 1, pix.shape) * NOISE_PER_SIZE * sizes[:, None], sizes

    return _ring_views(np.random.default_rng(seed), observe)[:4]


def test_the_mapper_weighs_observations_by_keypoint_size():
    errors = {True: [], False: []}
    for seed in range(3):
        features, pairs, Rs, ts = _synthetic_views_with_sizes(seed)
        centers_true = -np.einsum("vji,vj->vi", Rs, ts)
        for weigh in (True, False):
            models, _, _ = reconstruct_models(features, pairs, K,
                                              SfMSettings(weight_by_size=weigh))
            model = models[0]
            assert model.registered.all()
            err = camera_set_error(model.R, model.centers, Rs, centers_true)
            errors[weigh].append(np.median(err.center_errors))
    assert np.mean(errors[True]) < 0.8 * np.mean(errors[False])
    assert all(w < u for w, u in zip(errors[True], errors[False]))


def test_extracted_features_carry_the_keypoint_sizes(rendered_pair):
    img = rendered_pair[0]
    features = extract_features(img)
    keypoints = cv2.SIFT_create(8000, enable_precise_upscale=True).detect(
        cv2.cvtColor(img, cv2.COLOR_BGR2GRAY) if img.ndim == 3 else img, None)
    assert features.sizes.shape == (len(features.keypoints),)
    assert len(features.keypoints) == len(keypoints)
    np.testing.assert_allclose(features.sizes, [k.size for k in keypoints])
    assert features.sizes.min() > 1.0 and features.sizes.max() > 4 * np.median(features.sizes)


@pytest.mark.parametrize("weigh", [True, False])
def test_features_without_sizes_weigh_the_same(weigh):
    """Keypoints without sizes (e.g. from another program): every observation weighs one,
    whatever the setting, and the result is the unweighted one."""
    features, pairs, Rs, ts = _synthetic_views_with_sizes(0)
    bare = [ViewFeatures(f.keypoints, f.descriptors, f.colors) for f in features]
    a = reconstruct_models(bare, pairs, K, SfMSettings(weight_by_size=weigh))[0][0]
    b = reconstruct_models(features, pairs, K, SfMSettings(weight_by_size=False))[0][0]
    np.testing.assert_allclose(a.R, b.R, atol=1e-12)
    np.testing.assert_allclose(a.points3d, b.points3d, atol=1e-9)
