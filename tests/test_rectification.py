import numpy as np
import pytest

from scene3D.geometry import project
from scene3D.geometry.rectification import rectify_pair, rectify_points

from .helpers import correspondences


def test_rectified_matches_share_a_row_and_size_is_kept(rendered_pair):
    img1, img2, K, R, t = rendered_pair
    rect = rectify_pair(img1, img2, K, R, t)
    # 640x480 stays 640x480 (the book passed (height, width) and got 480x640).
    assert rect.img1.shape == img1.shape and rect.img2.shape == img2.shape
    _, pts1, pts2 = correspondences(K, R, t, n=100)
    r1 = rectify_points(pts1, K, rect.R1, rect.P1)
    r2 = rectify_points(pts2, K, rect.R2, rect.P2)
    np.testing.assert_allclose(r1[:, 1], r2[:, 1], atol=1e-6)
    # P2 encodes the baseline along x of the rectified frame.
    assert abs(rect.P2[0, 3] / rect.P2[0, 0]) == pytest.approx(np.linalg.norm(t))


def test_rectified_images_are_consistent_with_the_maps(rendered_pair):
    """A scene point appears on the same row, with the same colour, in both rectified images."""
    from scene3D.evaluation.synthetic import render_planes

    img1, img2, K, R, t = rendered_pair
    rect = rectify_pair(img1, img2, K, R, t, alpha=0.0)
    _, depth = render_planes(K, np.eye(3), np.zeros(3), supersample=1)
    x, y = 300, 220
    X = depth[y, x] * np.linalg.inv(K) @ np.array([x, y, 1.0])
    X = X[None, :]
    y1 = rectify_points(project(X, K, np.eye(3), np.zeros(3)), K, rect.R1, rect.P1)[0, 1]
    y2 = rectify_points(project(X, K, R, t), K, rect.R2, rect.P2)[0, 1]
    assert abs(y1 - y2) < 1e-6
    x1 = rectify_points(project(X, K, np.eye(3), np.zeros(3)), K, rect.R1, rect.P1)[0, 0]
    x2 = rectify_points(project(X, K, R, t), K, rect.R2, rect.P2)[0, 0]
    patch1 = rect.img1[int(round(y1)) - 2:int(round(y1)) + 3, int(round(x1)) - 2:int(round(x1)) + 3]
    patch2 = rect.img2[int(round(y2)) - 2:int(round(y2)) + 3, int(round(x2)) - 2:int(round(x2)) + 3]
    assert patch1.std() > 1  # real texture, not a black border
    assert np.abs(patch1.astype(float) - patch2.astype(float)).mean() < 12


def test_a_shifted_image_2_keeps_rows_and_its_Q_gives_the_point(rendered_pair):
    """``shift2_px`` moves rectified image 2 along x: disparities drop by the shift, rows
    and depths stay (Q includes the shift)."""
    import cv2

    img1, img2, K, R, t = rendered_pair
    plain = rectify_pair(img1, img2, K, R, t, alpha=0.0)
    shifted = rectify_pair(img1, img2, K, R, t, alpha=0.0, shift2_px=40.0)
    X, pts1, pts2 = correspondences(K, R, t, n=20)
    x1 = rectify_points(pts1, K, shifted.R1, shifted.P1)
    x2 = rectify_points(pts2, K, shifted.R2, shifted.P2)
    x2_plain = rectify_points(pts2, K, plain.R2, plain.P2)
    np.testing.assert_allclose(x2[:, 0], x2_plain[:, 0] + 40.0, atol=1e-6)
    np.testing.assert_allclose(x2[:, 1], x1[:, 1], atol=1e-6)
    np.testing.assert_array_equal(shifted.img1, plain.img1)
    # Q maps (x, y, d) with the shifted disparity to the point in the rectified frame 1.
    disparity = np.zeros(img1.shape[:2], np.float32)
    u, v = np.rint(x1[0]).astype(int)
    disparity[v, u] = x1[0, 0] - x2[0, 0]
    point = cv2.reprojectImageTo3D(disparity, shifted.Q)[v, u]
    expected = shifted.R1 @ X[0]
    np.testing.assert_allclose(point[2], expected[2], rtol=1e-5)  # depth: from d alone
