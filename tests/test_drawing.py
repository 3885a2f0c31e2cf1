"""Figures drawn with OpenCV: what they show, where; and the book's Figures built on them."""

import cv2
import numpy as np
from matplotlib.figure import Figure

from scene3D.viz.drawing import (
    draw_epipolar_lines,
    draw_optic_flow,
    encode_png,
    epipolar_colors,
    frustum_corners,
    render_point_cloud,
    robust_extent,
    subsample_indices,
    titled,
)
from scene3D.viz.plotting import plot_epipolar_lines, plot_optic_flow


def test_optic_flow_arrow_runs_from_point_to_match():
    img = np.full((100, 200, 3), 128, np.uint8)
    raster = draw_optic_flow(img, np.array([[20.0, 50.0]]), np.array([[120.0, 50.0]]))
    assert raster.image.shape == img.shape and "1 tracks" in raster.title
    row = raster.image[50]
    yellow = (row[:, 0] < 80) & (row[:, 1] > 200) & (row[:, 2] > 200)
    assert yellow[30:110].all() and not yellow[130:].any()
    assert np.array_equal(img, np.full((100, 200, 3), 128, np.uint8))  # input untouched


def test_epipolar_line_passes_through_its_match():
    """For F of a pure horizontal translation (rectified pair), the line of x1 in image 2 is
    the row of x1; it is drawn in its colour across image 2 and through x2."""
    F = np.array([[0, 0, 0], [0, 0, -1], [0, 1, 0]], dtype=float)
    img = np.zeros((80, 120, 3), np.uint8)
    pts1, pts2 = np.array([[30.0, 40.0]]), np.array([[70.0, 40.0]])
    raster = draw_epipolar_lines(img, img, F, pts1, pts2, num_lines=5)
    assert raster.image.shape == (80, 2 * 120 + 8, 3)
    colour = (255 * epipolar_colors(1)[0][::-1]).astype(int)
    right = raster.image[:, 128:]
    np.testing.assert_allclose(right[40, 5], colour, atol=30)  # anti-aliased
    np.testing.assert_allclose(right[40, 110], colour, atol=30)
    assert right[20, 5].max() == 0 and right[60, 60].max() == 0


def test_point_cloud_view_and_z_buffer():
    # Two points on the view's line of sight through the box centre: the nearer one wins.
    points = np.array([[0.0, 0, 4], [0, 0, 6], [-1, -1, 3], [1, 1, 7]])
    colors = np.array([[255, 0, 0], [0, 0, 255], [0, 255, 0], [0, 255, 0]], np.uint8)
    raster = render_point_cloud(points, colors, size=(200, 150), yaw_deg=0.0, pitch_deg=0.0)
    centre = raster.image[74:76, 99:101].reshape(-1, 3)
    assert (centre == [0, 0, 255]).all(axis=1).any()  # red (BGR) in front of blue
    assert not (raster.image.reshape(-1, 3) == [255, 0, 0]).all(axis=1).any()
    assert "4 points" in raster.title


def test_frustum_corners_in_world_frame():
    K = np.array([[100.0, 0, 49.5], [0, 100, 39.5], [0, 0, 1]])
    R = np.array([[0.0, 0, 1], [0, 1, 0], [-1, 0, 0]])  # turned 90 deg about y
    C = np.array([2.0, 0, 0])
    corners = frustum_corners(R[None], (-R @ C)[None], K, (100, 80), 2.0)[0]
    np.testing.assert_allclose(corners[0], C)
    # The optical axis (camera z) points along world R^T e_z = -x; corners 2 deep along it.
    np.testing.assert_allclose((corners[1:] - C) @ R[2], 2.0)


def test_helpers():
    np.testing.assert_array_equal(subsample_indices(10, 4), [0, 2, 5, 7])
    np.testing.assert_array_equal(subsample_indices(3, 4), [0, 1, 2])
    pts = np.column_stack([np.arange(101.0), np.zeros(101), np.zeros(101)])
    lo, hi = robust_extent(pts)
    assert lo[0] == 2 and hi[0] == 98
    img = np.zeros((10, 300, 3), np.uint8)
    png = encode_png(titled(type("R", (), {"image": img, "title": "t"})()))
    decoded = cv2.imdecode(np.frombuffer(png, np.uint8), cv2.IMREAD_COLOR)
    assert decoded.shape == (40, 300, 3) and decoded[:30].mean() > 200


def test_book_figures_show_the_drawings():
    img = np.full((60, 90, 3), 100, np.uint8)
    fig = plot_optic_flow(img, np.array([[10.0, 10]]), np.array([[40.0, 20]]))
    assert isinstance(fig, Figure)
    shown = fig.axes[0].images[0].get_array()
    expected = draw_optic_flow(img, np.array([[10.0, 10]]), np.array([[40.0, 20]])).image
    np.testing.assert_array_equal(shown, expected[..., ::-1])
    F = np.array([[0, 0, 0], [0, 0, -1], [0, 1, 0]], dtype=float)
    fig = plot_epipolar_lines(img, img, F, np.array([[10.0, 30]]), np.array([[50.0, 30]]))
    assert isinstance(fig, Figure) and "Epipolar" in fig.axes[0].get_title()
