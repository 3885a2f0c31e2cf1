"""Channel order where arrays come in (scene3D.io.images.bgr_order): BGR as OpenCV by
default, ``rgb=True`` for RGB arrays (PIL, imageio), in the pair API, the book's class
and reconstruct_views; the points' colours come out RGB and right both ways."""

import numpy as np
import pytest

from scene3D import SceneReconstruction3D, reconstruct_views
from scene3D.evaluation.synthetic import render_planes
from scene3D.features import Matches
from scene3D.io.images import bgr_order
from scene3D.twoview import reconstruct_two_view

from .helpers import correspondences

#: Blue strongest, then green, then red: a swap shows as red > blue.
TINT_BGR = np.array([1.0, 0.6, 0.25])


def tinted(image: np.ndarray) -> np.ndarray:
    """A grey rendering as a BGR image of one hue (blue-ish)."""
    grey = image if image.ndim == 2 else image.mean(axis=2)
    return np.round(grey[..., None] * TINT_BGR).astype(np.uint8)


def assert_blue_points(colors: np.ndarray) -> None:
    """RGB colours of the tint: red < green < blue wherever the point is not black."""
    lit = colors.max(axis=1) > 20
    assert lit.mean() > 0.9
    r, g, b = colors[lit].astype(int).T
    assert np.all(r <= g) and np.all(g <= b) and np.all(r < b)


def test_bgr_order_swaps_only_rgb_arrays():
    rgba = np.arange(2 * 2 * 4, dtype=np.uint8).reshape(2, 2, 4)
    np.testing.assert_array_equal(bgr_order(rgba, rgb=True), rgba[..., [2, 1, 0, 3]])
    rgb = rgba[..., :3]
    np.testing.assert_array_equal(bgr_order(rgb, rgb=True), rgb[..., ::-1])
    assert bgr_order(rgb) is rgb and bgr_order("a.jpg", rgb=True) == "a.jpg"
    grey = rgb[..., 0]
    assert bgr_order(grey, rgb=True) is grey


def test_the_pair_api_gives_the_same_colours_from_bgr_and_rgb(camera, true_pose):
    """Colour a known function of the pixel: B = x // 3, G = y // 2, R = 200; the points'
    RGB colours are (200, y // 2, x // 3) at their pixel in image 1, both ways."""
    R, t = true_pose
    _, pts1, pts2 = correspondences(camera, R, t, n=120)
    matches = Matches(pts1, pts2, "SIFT", (120, 120))
    y, x = np.mgrid[0:480, 0:640]
    bgr = np.stack([x // 3, y // 2, np.full_like(x, 200)], axis=2).astype(np.uint8)
    from_bgr = reconstruct_two_view(bgr, matches, camera)
    from_rgb = reconstruct_two_view(bgr[..., ::-1].copy(), matches, camera, rgb=True)
    px = np.clip(np.rint(from_bgr.pts1).astype(int), 0, [639, 479])
    expected = np.column_stack([np.full(len(px), 200), px[:, 1] // 2, px[:, 0] // 3])
    np.testing.assert_array_equal(from_bgr.colors, expected)
    np.testing.assert_array_equal(from_rgb.colors, expected)
    # Unsaid, an RGB array is taken as BGR: the colours come out swapped.
    unsaid = reconstruct_two_view(bgr[..., ::-1].copy(), matches, camera)
    np.testing.assert_array_equal(unsaid.colors, expected[:, ::-1])


@pytest.fixture(scope="module")
def blue_views(camera, true_pose):
    """The two renderings of the box scene (rendered_pair's) in the tint, BGR."""
    R, t = true_pose
    poses = [(np.eye(3), np.zeros(3)), (R, t)]
    return [tinted(render_planes(camera, Rv, tv)[0]) for Rv, tv in poses]


def test_the_book_class_takes_rgb_arrays(camera, blue_views):
    results = []
    for images, rgb in ((blue_views, False), ([v[..., ::-1].copy() for v in blue_views], True)):
        scene = SceneReconstruction3D(camera, np.zeros(5))
        scene.load_image_pair(*images, use_pyr_down=False, rgb=rgb)
        np.testing.assert_array_equal(scene.img1, blue_views[0])
        results.append(scene.reconstruct())
    assert_blue_points(results[0].colors)
    np.testing.assert_array_equal(results[1].colors, results[0].colors)


def test_reconstruct_views_takes_rgb_arrays(camera, blue_views):
    as_bgr = reconstruct_views(blue_views, camera, max_width=None)
    as_rgb = reconstruct_views([v[..., ::-1].copy() for v in blue_views], camera,
                               max_width=None, rgb=True)
    colors = as_bgr.models[0].colors
    assert_blue_points(colors)
    np.testing.assert_array_equal(as_rgb.models[0].colors, colors)
    np.testing.assert_array_equal(as_rgb.models[0].points3d, as_bgr.models[0].points3d)
