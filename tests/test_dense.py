"""Dense reconstruction against rendered depth (synthetic) and the sparse cloud (fountain)."""

import numpy as np
import pytest

from scene3D import SceneReconstruction3D
from scene3D.dense import compute_disparity, disparity_range
from scene3D.geometry import project
from scene3D.synthetic import render_planes


def test_disparity_range_covers_the_sparse_disparities_with_margin():
    lo, hi = disparity_range(np.array([20.0, 30.0, 45.0, 60.0]))
    assert lo <= 20 - 8 and hi >= 60 + 8
    assert (hi - lo) % 16 == 0


def test_constant_shift_gives_a_constant_disparity():
    rng = np.random.default_rng(0)
    texture = rng.integers(0, 255, (120, 200), dtype=np.uint8)
    texture = np.dstack([texture] * 3)
    left = texture[:, 20:180]
    right = texture[:, 32:192]  # left pixel x shows what right pixel x - 12 shows
    disp = compute_disparity(left, right, 0, 32)
    valid = np.isfinite(disp)
    assert valid.mean() > 0.5
    assert np.median(disp[valid]) == pytest.approx(12.0, abs=0.1)


@pytest.fixture(scope="module")
def synthetic_dense(rendered_pair):
    img1, img2, K, R, t = rendered_pair
    scene = SceneReconstruction3D(K)
    scene.load_image_pair(img1, img2)
    return scene, scene.dense_point_cloud(), K, R, t


def test_dense_points_lie_on_the_rendered_surfaces(synthetic_dense):
    scene, dense, K, R, t = synthetic_dense
    _, depth = render_planes(K, np.eye(3), np.zeros(3), supersample=1)
    metric = dense.points3d * np.linalg.norm(t)  # unit baseline -> the scene's units
    pix = np.rint(project(metric, K, np.eye(3), np.zeros(3))).astype(int)
    inside = (pix[:, 0] >= 0) & (pix[:, 0] < 640) & (pix[:, 1] >= 0) & (pix[:, 1] < 480)
    true_z = depth[pix[inside, 1], pix[inside, 0]]
    finite = np.isfinite(true_z)
    rel = np.abs(metric[inside][finite, 2] - true_z[finite]) / true_z[finite]
    # Stated bound: median depth error below 1 % of the depth; 90 % of points within 3 %.
    assert np.median(rel) < 0.01
    assert np.percentile(rel, 90) < 0.03
    assert dense.num_points > 0.3 * 640 * 480  # most of the image is textured surface
    assert dense.colors.shape == (dense.num_points, 3)


def test_dense_agrees_with_sparse_on_the_book_pair(fountain):
    from scene3D.datasets import read_strecha_camera

    cam = read_strecha_camera(fountain / "gt_dense_cameras" / "0004.jpg.camera")
    scene = SceneReconstruction3D(cam.K)
    scene.load_image_pair(fountain / "images" / "0004.jpg", fountain / "images" / "0005.jpg")
    sparse = scene.reconstruct()
    dense = scene.dense_point_cloud()
    assert dense.num_points >= 100 * sparse.num_points
    # Compare depths where both exist: the dense point at each sparse point's rectified pixel.
    from scene3D.rectification import rectify_points

    rect = dense.rectified
    r1 = np.rint(rectify_points(sparse.pts1, scene.K, rect.R1, rect.P1)).astype(int)
    index = {(x, y): i for i, (x, y) in enumerate(dense.pixels.astype(int))}
    pairs = [(i, index[(x, y)]) for i, (x, y) in enumerate(r1) if (x, y) in index]
    assert len(pairs) > 200  # sparse points whose rectified pixel has a dense point
    s_idx, d_idx = np.array(pairs).T
    z_sparse = np.linalg.norm(sparse.points3d[s_idx], axis=1)
    z_dense = np.linalg.norm(dense.points3d[d_idx], axis=1)
    # Stated bound: median relative range difference below 1 %.
    assert np.median(np.abs(z_dense - z_sparse) / z_sparse) < 0.01
